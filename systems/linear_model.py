"""The toolkit's one linear-model type: a discrete single-input, single-output state space.

    x(k+1) = A x(k) + B u(k) [+ K e(k)],   y(k) = C x(k) + D u(k) [+ e(k)]

u and y are deviations from an operating point (u_op, y_op), so the model says that the input
u_op + u(k) drives the output y_op + y(k). The bracketed terms are the innovations form
(Eq. 25) of an identified model, with e white of variance σ²; they describe the output's noise, not
a physical input, so everything here but the innovations fields concerns the deterministic part
from u to y.

Every model in the toolkit is one of these: the paper's identified model (Eq. 26), a model
`maskless identify` fits or a model file loads, the pneumatic plant linearised for the offset-free
design, the controllers as the stability analysis closes them, and the loops it builds. So there is
one DC gain, one set of poles and one steady-target solver, each written once here.
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from maskless.errors import ModelError

# A pole closer than this to z = 1 is an integrator: the model's steady output per unit input is
# unbounded (or, next to it, meaningless), so it has no DC gain and no steady target.
INTEGRATOR_DISTANCE = 1e-6
# Largest number of complex entries of one batch of (zI - A) matrices, to bound memory for
# large models.
_BATCH_ENTRIES = 2**22


def _as_matrix(value, name: str, shape: tuple[int, int], meaning: str) -> np.ndarray:
    """A finite, read-only float copy of ``value`` with the given shape, or a ModelError."""
    array = np.array(value, dtype=float)
    if array.shape != shape:
        raise ModelError(f"{name} must have shape {shape} ({meaning}), got {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ModelError(f"{name} must be finite")
    array.setflags(write=False)
    return array


def _finite_number(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ModelError(f"{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ModelError(f"{name} must be finite, got {value}")
    return float(value)


def _format_pole(pole: complex) -> str:
    return f"{pole.real:.9g}" if pole.imag == 0 else f"{complex(pole):.9g}"


@dataclass(frozen=True, eq=False)  # eq=False: element-wise array equality has no single truth
class LinearModel:
    """A discrete SISO model of deviations from an operating point (see the module docstring).

    The matrices are stored as read-only float copies; a wrong shape, a non-finite entry or a bad
    sample period raises ModelError naming the field. A static gain has n = 0 states: A (0, 0),
    B (0, 1), C (1, 0), D (1, 1); see ``static_gain``.

    Attributes:
        A: State matrix (n, n).
        B: Input matrix (n, 1), in output units per input unit when C is dimensionless.
        C: Output matrix (1, n).
        D: Feedthrough (1, 1).
        sample_period_s: Ts (s), positive.
        operating_input: u_op, the input the model is linearised around (``input_unit``).
        operating_output: y_op, the output the model is linearised around (``output_unit``).
        input_unit: the input's unit, e.g. "A" for a valve current or "m" for a lift command;
            empty when not stated (a loop transfer, or a fit to a record of unknown units).
        output_unit: the output's unit, e.g. "m"; empty when not stated.
        K: innovations gain (n, 1) of an identified model; None for a model without a noise
            description.
        innovations_variance: σ², the one-step prediction error's variance (``output_unit``²)
            of an identified model; None when not known.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    sample_period_s: float
    operating_input: float = 0.0
    operating_output: float = 0.0
    input_unit: str = ""
    output_unit: str = ""
    K: np.ndarray | None = None
    innovations_variance: float | None = None

    def __post_init__(self):
        """Checks shapes, numbers and units (ModelError); stores arrays and numbers as floats."""
        A = np.asarray(self.A, dtype=float)
        if A.ndim != 2 or A.shape[0] != A.shape[1]:
            raise ModelError(f"A must be a square 2-D array (n, n), got shape {A.shape}")
        n = A.shape[0]
        fields = {
            "A": _as_matrix(A, "A", (n, n), "n x n"),
            "B": _as_matrix(self.B, "B", (n, 1), "n x 1, single input"),
            "C": _as_matrix(self.C, "C", (1, n), "1 x n, single output"),
            "D": _as_matrix(self.D, "D", (1, 1), "SISO feedthrough"),
            "operating_input": _finite_number(self.operating_input, "operating_input"),
            "operating_output": _finite_number(self.operating_output, "operating_output"),
        }
        if self.K is not None:
            fields["K"] = _as_matrix(self.K, "K", (n, 1), "n x 1, innovations gain")
        period = self.sample_period_s
        if isinstance(period, bool) or not isinstance(period, int | float | np.floating):
            raise ModelError(f"sample_period_s must be a number of seconds, got {period!r}")
        if not (math.isfinite(period) and period > 0.0):
            raise ModelError(f"sample_period_s must be positive and finite, got {period}")
        fields["sample_period_s"] = float(period)
        if self.innovations_variance is not None:
            variance = _finite_number(self.innovations_variance, "innovations_variance")
            if variance < 0.0:
                raise ModelError(f"innovations_variance must be >= 0, got {variance}")
            fields["innovations_variance"] = variance
        for name in ("input_unit", "output_unit"):
            if not isinstance(getattr(self, name), str):
                raise ModelError(f"{name} must be a string, got {getattr(self, name)!r}")
        for name, value in fields.items():
            object.__setattr__(self, name, value)

    @classmethod
    def static_gain(cls, gain: float, sample_period_s: float) -> "LinearModel":
        """A memoryless gain y = gain · u (no states), e.g. a proportional controller."""
        return cls(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[gain]], sample_period_s)

    @property
    def order(self) -> int:
        """Number of states n."""
        return self.A.shape[0]

    @property
    def nyquist_rad_s(self) -> float:
        """π / Ts (rad/s)."""
        return math.pi / self.sample_period_s

    def poles(self) -> np.ndarray:
        """Eigenvalues of A (complex, n of them)."""
        return np.linalg.eigvals(self.A).astype(complex)

    def is_stable(self) -> bool:
        """Every pole strictly inside the unit circle (``stable``)."""
        return stable(self.poles())

    def dc_gain(self) -> float:
        """The steady output per unit steady input, C (I - A)⁻¹ B + D.

        In ``output_unit`` per ``input_unit``.

        Raises:
            ModelError: a pole within ``INTEGRATOR_DISTANCE`` of z = 1, which it names.
        """
        self._refuse_integrator()
        if self.order == 0:
            return float(self.D[0, 0])
        gain = (self.C @ np.linalg.solve(np.eye(self.order) - self.A, self.B))[0, 0]
        return float(gain + self.D[0, 0])

    def steady_target(self, hold_input: bool = False) -> tuple[np.ndarray, float]:
        """(x_ss, u_ss): the equilibrium that holds the output at one unit of deviation.

        The exact solution of (I - A) x = B u, C x + D u = 1. With ``hold_input`` the input stays
        at its operating point (u_ss = 0), as for a regulator with no feedforward path (the paper's
        LQG); such an equilibrium exists only when A has an eigenvalue at 1, so x_ss is then the
        least-squares solution of (I - A) x = 0, C x = 1.

        Args:
            hold_input: keep u at the operating point instead of solving for it.

        Returns:
            x_ss (n,) per unit output (state units per ``output_unit``) and u_ss per unit output
            (``input_unit`` per ``output_unit``; 0.0 with ``hold_input``).

        Raises:
            ModelError: (without ``hold_input``) a pole within ``INTEGRATOR_DISTANCE`` of z = 1,
                which it names, or an input that does not reach the output in steady state.
        """
        n = self.order
        rhs = np.concatenate([np.zeros(n), [1.0]])
        if hold_input:
            lhs = np.vstack([np.eye(n) - self.A, self.C])
            x_ss, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
            return x_ss, 0.0
        self._refuse_integrator()
        lhs = np.block([[np.eye(n) - self.A, -self.B], [self.C, self.D]])
        try:
            solution = np.linalg.solve(lhs, rhs)
        except np.linalg.LinAlgError:
            raise ModelError(
                "the model has no steady state that holds its output at a reference (its input "
                "does not reach the output in steady state: its DC gain is 0)"
            ) from None
        return solution[:n], float(solution[n])

    def _refuse_integrator(self) -> None:
        if self.order == 0:
            return
        poles = self.poles()
        closest = poles[np.argmin(np.abs(1.0 - poles))]
        if abs(1.0 - closest) < INTEGRATOR_DISTANCE:
            raise ModelError(
                f"the model has a pole at z = {_format_pole(closest)} (an integrator, or next to "
                "one), so its steady output per unit input (its DC gain) is unbounded"
            )

    def transfer_function(self, z) -> np.ndarray:
        """G(z) = C (zI - A)⁻¹ B + D at each complex z (any shape), solving rather than inverting.

        Raises:
            numpy.linalg.LinAlgError: if some z is a pole of the model.
        """
        z = np.asarray(z, dtype=complex)
        flat = z.ravel()
        n = self.order
        if n == 0:
            return np.full(z.shape, self.D[0, 0], dtype=complex)
        response = np.empty(flat.shape, dtype=complex)
        batch = max(1, _BATCH_ENTRIES // (n * n))
        identity = np.eye(n)
        for start in range(0, flat.size, batch):
            zs = flat[start : start + batch]
            resolvent_B = np.linalg.solve(
                zs[:, None, None] * identity - self.A, np.broadcast_to(self.B, (zs.size, n, 1))
            )
            response[start : start + batch] = (self.C @ resolvent_B)[:, 0, 0] + self.D[0, 0]
        return response.reshape(z.shape)

    def frequency_response(self, omega_rad_s) -> np.ndarray:
        """G(z) at z = exp(j ω Ts).

        Args:
            omega_rad_s: Frequencies ω (rad/s), any shape, finite.

        Returns:
            Complex array of the same shape as ``omega_rad_s``.

        Raises:
            ModelError: if a frequency is not finite.
            numpy.linalg.LinAlgError: if some z is a pole of the model (on the unit circle).
        """
        omega = np.asarray(omega_rad_s, dtype=float)
        if not np.all(np.isfinite(omega)):
            raise ModelError("omega_rad_s must be finite")
        return self.transfer_function(np.exp(1j * omega * self.sample_period_s))

    def controller(self, A, B, C, D) -> "LinearModel":
        """A controller of this plant, x+ = A x + B y, u = C x + D y, as a LinearModel.

        Its input is this model's output and its output this model's input, so their operating
        points, units and sample period are this model's, swapped.
        """
        return LinearModel(
            A,
            B,
            C,
            D,
            self.sample_period_s,
            operating_input=self.operating_output,
            operating_output=self.operating_input,
            input_unit=self.output_unit,
            output_unit=self.input_unit,
        )

    def output_subtracted_from(self, total: float) -> "LinearModel":
        """The same model with output total - y.

        This turns a camera-to-head distance into the head's height above the table, ``total``
        being the camera's height (``output_unit``).

        C, D and K change sign (the innovations of -y are -e, with the same variance) and the
        operating output becomes total - y_op.
        """
        return replace(
            self,
            C=-self.C,
            D=-self.D,
            K=None if self.K is None else -self.K,
            operating_output=total - self.operating_output,
        )


def stable(poles, tol: float = 0.0) -> bool:
    """True when every pole lies strictly inside the circle of radius 1 - tol.

    Args:
        poles: Complex poles, 1-D (an empty set is stable).
        tol: Stability margin on the radius, 0 <= tol < 1.

    Raises:
        ModelError: if ``poles`` is not 1-D and finite, or ``tol`` is outside [0, 1).
    """
    poles = np.asarray(poles)
    if poles.ndim != 1:
        raise ModelError(f"poles must be a 1-D array (n,), got shape {poles.shape}")
    if not np.all(np.isfinite(poles)):
        raise ModelError("poles must be finite")
    if not (0.0 <= tol < 1.0):
        raise ModelError(f"tol must lie in [0, 1), got {tol}")
    return bool(np.all(np.abs(poles) < 1.0 - tol))


def observer_form(a, numerator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B, C) of q^-1 N(q) / A(q) in the observer canonical form.

    A(q) = 1 + a_1 q^-1 + ... + a_n q^-n and N(q) = numerator[0] + numerator[1] q^-1 + ...,
    at least as long as ``a``; x1 is the output and each state feeds the one before it. It is
    identification's working form (``innovations_model``) and a Hammerstein model's.
    """
    size = len(numerator)
    A = np.zeros((size, size))
    A[: len(a), 0] = -np.asarray(a)
    A[: size - 1, 1:] = np.eye(size - 1)
    return A, np.asarray(numerator, dtype=float).reshape(size, 1), np.eye(1, size)
