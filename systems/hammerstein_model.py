"""A Hammerstein model: each valve's static map, then one linear system for all of them.

    y(k) = y_op + sum_i q^-d B_i(q) / A_i(q) f_i(u_i(k))

with f_i a valve's monotone map from coil current to opening (``valve_map.ValveMap``, 0 below the
starting current, 1 from saturation on), A_i(q) = 1 + a_i1 q^-1 + ... + a_in q^-n,
B_i(q) = b_i1 + b_i2 q^-1 + ... + b_in q^-(n-1) and d >= 1 samples of input delay. y_op is the
output at rest with every valve shut. Each valve may have its own denominator (a split range opens
the inlet at high bladder pressures and the outlet at low ones, where the plant's time constants
differ); the estimator fits one shared by both (one bladder moves one head). Because each map is 1
at saturation, the scale between map and dynamics is fixed: B_i(1) / A_i(1) is the steady output
change from shut to fully open, and the static curve of a valve is that gain times its map.

It is the model ``analysis.identification.hammerstein`` estimates, that a model file holds and a
plant runs (``plant.hammerstein_plant``); the design uses one valve's linear part
(``valve_linear_model``) behind the maps' inverse.
"""

from dataclasses import dataclass

import numpy as np

from maskless.errors import ModelError
from maskless.systems.linear_model import LinearModel, observer_form, stable
from maskless.systems.plant.valve_map import ValveMap


@dataclass(frozen=True, eq=False)  # eq=False: element-wise array equality has no single truth
class HammersteinModel:
    """The model of the module docstring, in the record's units (or SI, loaded from a file).

    Attributes:
        maps: one ``ValveMap`` per input, currents in ``input_unit``.
        a: A_i(q) coefficients a_i1..a_in (inputs, n).
        b: B_i(q) coefficients (inputs, n), in ``output_unit`` per unit opening.
        input_delay_samples: d, samples from a current to its first effect (>= 1).
        operating_output: y_op, the steady output with every valve shut (``output_unit``).
        sample_period_s: Ts (s).
        input_unit: the currents' unit (e.g. "A", "mA"); empty when not stated.
        output_unit: the output's unit (e.g. "m"); empty when not stated.

    Raises:
        ModelError: naming the field, for shapes, non-finite numbers or a bad delay or period.
    """

    maps: tuple[ValveMap, ...]
    a: np.ndarray
    b: np.ndarray
    input_delay_samples: int
    operating_output: float
    sample_period_s: float
    input_unit: str = ""
    output_unit: str = ""

    def __post_init__(self):
        """Checks every field (ModelError) and stores the arrays read-only."""
        maps = tuple(self.maps)
        if not maps or not all(isinstance(m, ValveMap) for m in maps):
            raise ModelError(f"maps must be one or more ValveMap, got {self.maps!r}")
        a = np.array(self.a, dtype=float)
        b = np.array(self.b, dtype=float)
        if a.ndim != 2 or a.shape[0] != len(maps) or a.shape[1] < 1:
            raise ModelError(f"a must have shape ({len(maps)}, n >= 1) (inputs, n), got {a.shape}")
        if b.shape != a.shape:
            raise ModelError(f"b must have shape {a.shape} (inputs, n), got {b.shape}")
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise ModelError("a and b must be finite")
        delay = self.input_delay_samples
        if isinstance(delay, bool) or not isinstance(delay, int | np.integer) or delay < 1:
            raise ModelError(f"input_delay_samples = {delay!r}: expected an integer >= 1")
        _check_numbers_and_units(self)
        for array in (a, b):
            array.setflags(write=False)
        for name, value in (
            ("maps", maps),
            ("a", a),
            ("b", b),
            ("input_delay_samples", int(delay)),
            ("operating_output", float(self.operating_output)),
            ("sample_period_s", float(self.sample_period_s)),
        ):
            object.__setattr__(self, name, value)

    @property
    def order(self) -> int:
        """n, the order of each A_i(q)."""
        return self.a.shape[1]

    @property
    def inputs(self) -> int:
        """The number of valves."""
        return len(self.maps)

    def poles(self) -> np.ndarray:
        """The roots of each distinct z^n A_i(z) (complex, n per distinct denominator)."""
        distinct = np.unique(self.a, axis=0)
        return np.concatenate([np.roots(np.concatenate([[1.0], a])) for a in distinct]).astype(
            complex
        )

    def is_stable(self) -> bool:
        """Every pole strictly inside the unit circle."""
        return stable(self.poles())

    def dc_gains(self) -> np.ndarray:
        """B_i(1) / A_i(1) per input: the steady output change from shut to fully open.

        Raises:
            ModelError: some A_i(1) = 0 (an integrator: no steady output).
        """
        denominators = 1.0 + self.a.sum(axis=1)
        if np.any(denominators == 0.0):
            raise ModelError("A_i(1) = 0: the model integrates, so it has no static curve")
        return self.b.sum(axis=1) / denominators

    def static_curve(self, input_index: int, currents) -> np.ndarray:
        """The steady output change (``output_unit``) from shut, per current of one valve."""
        return self.dc_gains()[input_index] * self.maps[input_index].opening(
            np.asarray(currents, dtype=float)
        )

    def openings(self, u) -> np.ndarray:
        """(N, inputs) openings of the currents ``u`` (N, inputs)."""
        u = self._checked_input(u)
        return np.column_stack([m.opening(u[:, i]) for i, m in enumerate(self.maps)])

    def simulate(self, u) -> np.ndarray:
        """The simulated output (N,) for the currents ``u`` (N, inputs), from rest at u(0).

        The initial state is the steady state of the first sample's currents, for every input.
        """
        # Imported here: scipy.signal costs ~0.6 s of start-up that a plain simulation never needs.
        import scipy.signal

        openings = self.openings(u)
        y = np.full(openings.shape[0], self.operating_output)
        for i, numerator in enumerate(self.numerators()):
            denominator = np.concatenate([[1.0], self.a[i]])
            start = scipy.signal.lfilter_zi(numerator, denominator) * openings[0, i]
            y += scipy.signal.lfilter(numerator, denominator, openings[:, i], zi=start)[0]
        return y

    def numerators(self) -> np.ndarray:
        """(inputs, d + n) numerator coefficients over q^0 .. q^-(d+n-1), delay included."""
        return np.hstack([np.zeros((self.inputs, self.input_delay_samples)), self.b])

    def state_space(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(A, B, C) of the linear part: x+ = A x + B f(u), y = y_op + C x.

        One observer-form block per input (block diagonal A), each of n + d - 1 states (the
        delay's extra samples are states); B has one column per input (per unit opening).
        """
        numerators = self.numerators()[:, 1:]  # the q^-1 .. q^-(d+n-1) coefficients
        size = numerators.shape[1]
        A = np.zeros((self.inputs * size, self.inputs * size))
        B = np.zeros((self.inputs * size, self.inputs))
        C = np.zeros((1, self.inputs * size))
        for i in range(self.inputs):
            block = slice(i * size, (i + 1) * size)
            A[block, block], B[block, [i]], C[:, block] = observer_form(self.a[i], numerators[i])
        return A, B, C

    def valve_linear_model(self, input_index: int) -> LinearModel:
        """One valve's linear part, per unit of steady output, as a SISO ``LinearModel``.

        Its input is the valve's steady output change (``output_unit``: the map's opening times the
        DC gain), so its DC gain is 1, and its operating output y_op: the model a design sees
        behind the inverse of this valve's map. Its states are the d - 1 delayed inputs, then the
        linear part's modes (``modal_realisation``).

        Raises:
            ModelError: the valve has no steady effect (DC gain 0) or the model integrates.
        """
        gain = self.dc_gains()[input_index]
        if gain == 0.0:
            raise ModelError(
                f"input {input_index}: DC gain 0, so its static map cannot be inverted"
            )
        A, B, C = modal_realisation(
            self.a[input_index], self.b[input_index] / gain, self.input_delay_samples
        )
        return LinearModel(
            A=A,
            B=B,
            C=C,
            D=np.zeros((1, 1)),
            sample_period_s=self.sample_period_s,
            operating_output=self.operating_output,
            input_unit=self.output_unit,
            output_unit=self.output_unit,
        )

    def _checked_input(self, u) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        if u.ndim == 1 and self.inputs == 1:
            u = u[:, None]
        if u.ndim != 2 or u.shape[1] != self.inputs or u.shape[0] < 1:
            raise ValueError(
                f"u must have shape (N, {self.inputs}) (samples, inputs), got {u.shape}"
            )
        if not np.all(np.isfinite(u)):
            raise ValueError("u must be finite")
        return u


def _check_numbers_and_units(model: HammersteinModel) -> None:
    """ModelError naming the first number that is not finite (or positive) or unit not a string."""
    for name in ("operating_output", "sample_period_s"):
        value = getattr(model, name)
        if isinstance(value, bool) or not isinstance(value, int | float | np.floating):
            raise ModelError(f"{name} = {value!r}: expected a number")
        if not np.isfinite(value):
            raise ModelError(f"{name} = {value}: expected a finite number")
    if not model.sample_period_s > 0:
        raise ModelError(f"sample_period_s = {model.sample_period_s}: expected > 0")
    for name in ("input_unit", "output_unit"):
        if not isinstance(getattr(model, name), str):
            raise ModelError(f"{name} must be a string, got {getattr(model, name)!r}")


def modal_realisation(a, b, input_delay_samples: int):
    """(A, B, C) of q^-d B(q) / A(q): a chain of d - 1 delayed inputs, then the modes of B / A.

    Each state past the chain is one mode of the linear part (a real 2x2 block for a complex
    pair). The offset-free design weighs each state, and adds model error to it, in proportion
    to the output it holds in steady state, which is the share of the output that state carries
    only when the states are modes: on seed 0's order-2 workflow model (a zero between its poles),
    designed with the same process noise, the observer form (each state feeding the next) tracked
    with p95 0.840 mm, the real Schur form (a state holding almost nothing in steady state)
    9.0 mm, the modes 0.171 mm. A repeated pole has no modes of its own; there the observer form
    is kept.

    Args:
        a: A(q)'s coefficients a_1..a_n.
        b: B(q)'s coefficients b_1..b_n (B(q) = b_1 + b_2 q^-1 + ...).
        input_delay_samples: d >= 1.
    """
    # Imported here: scipy.linalg costs 0.4 s of start-up that a plain simulation never needs.
    import scipy.linalg

    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    n, chain = a.size, input_delay_samples - 1
    A_m, B_m, C_m = observer_form(a, b)  # q^-1 B(q) / A(q)
    poles, vectors = np.linalg.eig(A_m)
    if np.linalg.cond(vectors) < 1e6:  # distinct poles; a repeated one loses digits here
        poles, vectors = scipy.linalg.cdf2rdf(poles, vectors)
        A_m, B_m, C_m = poles, np.linalg.solve(vectors, B_m), C_m @ vectors
    A = np.zeros((chain + n, chain + n))
    B = np.zeros((chain + n, 1))
    A[chain:, chain:] = A_m
    if chain:
        A[1:chain, : chain - 1] = np.eye(chain - 1)
        A[chain:, [chain - 1]] = B_m
        B[0, 0] = 1.0
    else:
        B[:, :] = B_m
    C = np.hstack([np.zeros((1, chain)), C_m])
    return A, B, C
