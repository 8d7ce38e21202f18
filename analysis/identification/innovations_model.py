"""The single-output innovations-form model (Eq. 25) identification searches over.

Its polynomial parameterisation is the observer canonical form:

    x(k+1) = A x(k) + B u(k) + K e(k),   y(k) = C x(k) + e(k)
    A = [[-a1, 1, 0, ...], [-a2, 0, 1, ...], ..., [-an, 0, ..., 0]],  C = [1, 0, ..., 0],  D = 0

With m inputs (the inlet and the outlet valve) B is n x m: one numerator B_i(q) per input over the
common denominator A(q), so A(q) y = B_1(q) u_1 + ... + B_m(q) u_m + C(q) e. A single-input model
keeps b 1-D and u 1-D, and runs exactly the filters it always ran; an m-input one takes u of
shape (N, m) and sums each input's FIR part B_i(q) u_i before the one shared recursive filter.

It is the ARMAX model (Eq. 14-18) A(q) y = B(q) u + C(q) e with A(q) = 1 + a1 q⁻¹ + ... + an q⁻ⁿ,
B(q) = b1 q⁻¹ + ... + bn q⁻ⁿ and C(q) = A(q) + k1 q⁻¹ + ... + kn q⁻ⁿ (c_i = a_i + k_i), so one
class serves both. The one-step predictor (Eq. 19-20) is ŷ = (B/C) u + ((C - A)/C) y, which
``linear_filter.filter_signal`` runs in compiled code; its state is the model's state x, so an
initial state enters as the filter's (scipy lfilter's ``zi``: lfilter's transposed direct form is
this observer form).

This is identification's own working form: the estimators (PEM, ARMAX, ARX, N4SID) fit its
coefficients (a, b, k) and the report's figures run its filters. Identification's result is the
toolkit's ``LinearModel`` (``linear_model``): ``report.FittedModel.model`` and the model files
`maskless identify` writes; its poles, stability and DC gain are read there. ``LinearModel`` is
single-input, so an m-input model is read as one ``LinearModel`` per input (``input_index``).
"""

import math
from dataclasses import dataclass, replace

import numpy as np

from maskless.analysis.identification.linear_filter import filter_signal
from maskless.systems.linear_model import LinearModel, observer_form

# How far the response to a unit initial state may grow before an x(0) fit stops using later
# samples: a millionfold keeps the columns of its least squares finite and well scaled, and is
# far beyond what a stable model's transient reaches.
_INITIAL_STATE_GROWTH_LIMIT = 1e6


def samples_before_growth(poles: np.ndarray, samples: int) -> int:
    """How many of ``samples`` a response with ``poles`` takes to grow a millionfold.

    All of them when no pole lies outside the unit circle; at least one.
    """
    largest = float(np.max(np.abs(poles), initial=0.0))
    if largest <= 1.0:
        return samples
    return max(1, min(samples, int(math.log(_INITIAL_STATE_GROWTH_LIMIT) / math.log(largest))))


def impulse_response(denominator: np.ndarray, samples: int) -> np.ndarray:
    """The impulse response of 1 / D(q) (D = ``denominator``, leading 1) over ``samples``.

    For a stable D it is filtered only until it has decayed below 1e-16 of its start and is zero
    after: filtering on would crawl through subnormal numbers, which are slow to compute.
    """
    largest = float(np.max(np.abs(np.roots(denominator)), initial=0.0))
    span = samples
    if largest < 1.0:
        # Twice the pure decay time, plus the order, covers repeated roots' polynomial factor.
        decay = math.log(1e-16) / math.log(largest) if largest > 0.0 else 1.0
        span = min(samples, 2 * math.ceil(decay) + denominator.size)
    impulse = np.zeros(span)
    impulse[0] = 1.0
    response = np.zeros(samples)
    response[:span] = filter_signal([1.0], denominator, impulse)
    return response


def delayed_copies(signal: np.ndarray, delays) -> list[np.ndarray]:
    """``signal`` delayed by each of ``delays`` samples (zeros shifted in), as long as it."""
    return [np.concatenate([np.zeros(d), signal[: signal.size - d]]) for d in delays]


@dataclass(frozen=True)
class InnovationsModel:
    """An innovations-form model as the estimators parameterise it.

    Attributes:
        a: A(q) coefficients a1..an (n,).
        b: B(q) coefficients b1..bn (n,) of a single input, or (n, m), column i B_i(q) of input i;
            zeros for a model without input (ARMA).
        k: innovations gain K (n,).
        sample_period_s: Ts (s).
        initial_state: x(0) for the record it was estimated on (n,); zeros when not estimated.
    """

    a: np.ndarray
    b: np.ndarray
    k: np.ndarray
    sample_period_s: float
    initial_state: np.ndarray

    @property
    def order(self) -> int:
        """n, the number of states (and of coefficients in each of a, b and k)."""
        return self.a.size

    @property
    def inputs(self) -> int:
        """m, the number of inputs (1 for a single input's 1-D b)."""
        return 1 if self.b.ndim == 1 else self.b.shape[1]

    def input_alone(self, index: int) -> "InnovationsModel":
        """The single-input model from input ``index`` alone (b = B's column ``index``).

        The same A, K and x(0): with the other inputs held at their operating points it is the
        whole model. A single-input model is returned as it is for index 0.
        """
        if not 0 <= index < self.inputs:
            raise ValueError(f"index = {index}: expected 0 <= index < {self.inputs} inputs")
        return self if self.b.ndim == 1 else replace(self, b=self.b[:, index])

    def _input_drive(self, u: np.ndarray) -> np.ndarray:
        """Σ_i B_i(q) u_i of an m-input model: each input's FIR part, before 1/A or 1/C.

        The filters' initial state enters only through their shared denominator, so filtering
        this sum once is the sum of filtering each input.
        """
        u = np.asarray(u, float)
        if u.ndim != 2 or u.shape[1] != self.inputs:
            raise ValueError(f"u: expected shape (N, {self.inputs}), got {u.shape}")
        drive = np.zeros(u.shape[0])
        for column, numerator in zip(u.T, self.b.T, strict=True):
            drive += filter_signal(np.concatenate([[0.0], numerator]), [1.0], column)
        return drive

    @property
    def c(self) -> np.ndarray:
        """C(q) coefficients c1..cn of the noise model."""
        return self.a + self.k

    def linear_model(
        self, innovations_variance: float | None = None, input_index: int = 0
    ) -> LinearModel:
        """The model as a ``LinearModel``: the observer canonical A, B, C, D = 0 and K.

        It models the detrended record's deviations, in the record's units. ``LinearModel`` is
        single-input, so an m-input model gives the one from input ``input_index`` (the others
        held at their operating points): its poles, K and variance are the whole model's.

        Args:
            innovations_variance: σ² of the one-step prediction errors, when known.
            input_index: which input's column of B (0 for a single input).
        """
        if self.b.ndim == 2:
            return self.input_alone(input_index).linear_model(innovations_variance)
        A, B, C = observer_form(self.a, self.b)
        return LinearModel(
            A=A,
            B=B,
            C=C,
            D=np.zeros((1, 1)),
            K=self.k.reshape(self.order, 1),
            sample_period_s=self.sample_period_s,
            innovations_variance=innovations_variance,
        )

    def poles(self) -> np.ndarray:
        """Roots of A(z), the system's poles."""
        return np.roots(np.concatenate([[1.0], self.a]))

    def predictor_poles(self) -> np.ndarray:
        """Eigenvalues of A - K C (roots of C(z)); the predictor is stable when they are inside."""
        return np.roots(np.concatenate([[1.0], self.c]))

    def predict(self, u: np.ndarray, y: np.ndarray, initial_state=None) -> np.ndarray:
        """One-step-ahead prediction ŷ(k | k-1) from x(0) = ``initial_state``.

        Without ``initial_state`` it starts from the model's own x(0).
        """
        x0 = self.initial_state if initial_state is None else np.asarray(initial_state, float)
        denominator = np.concatenate([[1.0], self.c])
        if self.b.ndim == 2:
            drive = self._input_drive(u)
            drive += filter_signal(np.concatenate([[0.0], self.k]), [1.0], y)
            return filter_signal([1.0], denominator, drive, x0)
        from_u = np.concatenate([[0.0], self.b])
        from_y = np.concatenate([[0.0], self.k])
        predicted = filter_signal(from_u, denominator, u, x0)
        return predicted + filter_signal(from_y, denominator, y)

    def predict_k_steps(self, u: np.ndarray, y: np.ndarray, steps: int) -> np.ndarray:
        """The k-step-ahead prediction ŷ(t | t-k), from zero initial conditions.

        Ljung's form: ŷ = W_k G u + (1 - W_k) y with W_k = H̄_k H⁻¹, H = C/A the noise model and
        H̄_k its first k impulse-response terms; so W_k G = H̄_k B / C and W_k = H̄_k A / C, two
        filters with the denominator C.
        """
        if steps < 1:
            raise ValueError(f"steps = {steps}: expected at least 1")
        a_poly = np.concatenate([[1.0], self.a])
        c_poly = np.concatenate([[1.0], self.c])
        impulse = np.zeros(steps)
        impulse[0] = 1.0
        noise_head = filter_signal(c_poly, a_poly, impulse)  # h(0..k-1) of C/A
        from_y = np.convolve(noise_head, a_poly)
        if self.b.ndim == 2:
            # Each filter shares the denominator C: their FIR parts are summed, then filtered once.
            drive = filter_signal(noise_head, [1.0], self._input_drive(u))
            drive -= filter_signal(from_y, [1.0], y)
            return filter_signal([1.0], c_poly, drive) + y
        from_u = np.convolve(noise_head, np.concatenate([[0.0], self.b]))
        return filter_signal(from_u, c_poly, u) + y - filter_signal(from_y, c_poly, y)

    def simulate(self, u: np.ndarray, initial_state=None) -> np.ndarray:
        """The noise-free response to ``u`` (simulation, no measured outputs used)."""
        x0 = self.initial_state if initial_state is None else np.asarray(initial_state, float)
        if self.b.ndim == 2:
            drive = self._input_drive(u)
            return filter_signal([1.0], np.concatenate([[1.0], self.a]), drive, x0)
        return filter_signal(
            np.concatenate([[0.0], self.b]), np.concatenate([[1.0], self.a]), u, x0
        )

    def free_response(self, samples: int, initial_state=None) -> np.ndarray:
        """The output from the initial state alone, with no input."""
        no_input = np.zeros(samples) if self.b.ndim == 1 else np.zeros((samples, self.inputs))
        return self.simulate(no_input, initial_state)

    def initial_state_for(self, u: np.ndarray, y: np.ndarray, horizon: str) -> np.ndarray:
        """The x(0) that best explains another record, as MATLAB's ``compare`` estimates it.

        The response is linear in x(0), so x(0) comes from linear least squares. When the
        filter that horizon runs (the predictor 1/C for "one_step", the system 1/A for
        "simulation") is unstable, only the samples before its free response grows a
        millionfold are used, so no exploding response is ever evaluated.

        Args:
            u: the record's input, detrended, in the units of the model's input: (N,), or (N, m)
                for m inputs.
            y: the record's output, detrended, in the units of the model's output; as long as u.
            horizon: "one_step" fits the one-step prediction, "simulation" the simulated output.
        """
        if horizon == "one_step":
            denominator = np.concatenate([[1.0], self.c])
            used = samples_before_growth(self.predictor_poles(), y.size)
            base = self.predict(u[:used], y[:used], np.zeros(self.order))
        elif horizon == "simulation":
            denominator = np.concatenate([[1.0], self.a])
            used = samples_before_growth(self.poles(), y.size)
            base = self.simulate(u[:used], np.zeros(self.order))
        else:
            raise ValueError(f"horizon = {horizon!r}: expected 'one_step' or 'simulation'")
        # x0_j enters the filter's output as an impulse at sample j.
        columns = delayed_copies(impulse_response(denominator, used), range(self.order))
        solution, *_ = np.linalg.lstsq(np.column_stack(columns), y[:used] - base, rcond=None)
        return solution
