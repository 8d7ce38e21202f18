"""The single-input, single-output innovations-form model (Eq. 25) identification searches over.

Its polynomial parameterisation is the observer canonical form:

    x(k+1) = A x(k) + B u(k) + K e(k),   y(k) = C x(k) + e(k)
    A = [[-a1, 1, 0, ...], [-a2, 0, 1, ...], ..., [-an, 0, ..., 0]],  C = [1, 0, ..., 0],  D = 0

It is the ARMAX model (Eq. 14-18) A(q) y = B(q) u + C(q) e with A(q) = 1 + a1 q⁻¹ + ... + an q⁻ⁿ,
B(q) = b1 q⁻¹ + ... + bn q⁻ⁿ and C(q) = A(q) + k1 q⁻¹ + ... + kn q⁻ⁿ (c_i = a_i + k_i), so one
class serves both. The one-step predictor (Eq. 19-20) is ŷ = (B/C) u + ((C - A)/C) y, which scipy's
lfilter runs in C; its state is the model's state x, so an initial state enters as lfilter's zi
(lfilter's transposed direct form is this observer form).

This is identification's own working form: the estimators (PEM, ARMAX, ARX, N4SID) fit its
coefficients (a, b, k) and the report's figures run its filters. Identification's result is the
toolkit's ``LinearModel`` (``linear_model``): ``report.FittedModel.model`` and the model files
`maskless identify` writes; its poles, stability and DC gain are read there.
"""

from dataclasses import dataclass

import numpy as np
import scipy.signal

from maskless.systems.linear_model import LinearModel


@dataclass(frozen=True)
class InnovationsModel:
    """An innovations-form model as the estimators parameterise it.

    Attributes:
        a: A(q) coefficients a1..an (n,).
        b: B(q) coefficients b1..bn (n,); zeros for a model without input (ARMA).
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
    def c(self) -> np.ndarray:
        """C(q) coefficients c1..cn of the noise model."""
        return self.a + self.k

    def linear_model(self, innovations_variance: float | None = None) -> LinearModel:
        """The model as a ``LinearModel``: the observer canonical A, B, C, D = 0 and K.

        It models the detrended record's deviations, in the record's units.

        Args:
            innovations_variance: σ² of the one-step prediction errors, when known.
        """
        n = self.order
        A = np.zeros((n, n))
        A[:, 0] = -self.a
        A[: n - 1, 1:] = np.eye(n - 1)
        C = np.zeros((1, n))
        C[0, 0] = 1.0
        return LinearModel(
            A=A,
            B=self.b.reshape(n, 1),
            C=C,
            D=np.zeros((1, 1)),
            K=self.k.reshape(n, 1),
            sample_period_s=self.sample_period_s,
            innovations_variance=innovations_variance,
        )

    def predictor_poles(self) -> np.ndarray:
        """Eigenvalues of A - K C (roots of C(z)); the predictor is stable when they are inside."""
        return np.roots(np.concatenate([[1.0], self.c]))

    def predict(self, u: np.ndarray, y: np.ndarray, initial_state=None) -> np.ndarray:
        """One-step-ahead prediction ŷ(k | k-1) from x(0) = ``initial_state``.

        Without ``initial_state`` it starts from the model's own x(0).
        """
        x0 = self.initial_state if initial_state is None else np.asarray(initial_state, float)
        denominator = np.concatenate([[1.0], self.c])
        from_u = np.concatenate([[0.0], self.b])
        from_y = np.concatenate([[0.0], self.k])
        predicted, _ = scipy.signal.lfilter(from_u, denominator, u, zi=x0)
        return predicted + scipy.signal.lfilter(from_y, denominator, y)

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
        noise_head = scipy.signal.lfilter(c_poly, a_poly, impulse)  # h(0..k-1) of C/A
        from_u = np.convolve(noise_head, np.concatenate([[0.0], self.b]))
        from_y = np.convolve(noise_head, a_poly)
        return scipy.signal.lfilter(from_u, c_poly, u) + y - scipy.signal.lfilter(from_y, c_poly, y)

    def simulate(self, u: np.ndarray, initial_state=None) -> np.ndarray:
        """The noise-free response to ``u`` (simulation, no measured outputs used)."""
        x0 = self.initial_state if initial_state is None else np.asarray(initial_state, float)
        response, _ = scipy.signal.lfilter(
            np.concatenate([[0.0], self.b]), np.concatenate([[1.0], self.a]), u, zi=x0
        )
        return response

    def free_response(self, samples: int, initial_state=None) -> np.ndarray:
        """The output from the initial state alone, with no input."""
        return self.simulate(np.zeros(samples), initial_state)

    def initial_state_for(self, u: np.ndarray, y: np.ndarray, horizon: str) -> np.ndarray:
        """The x(0) that best explains another record, as MATLAB's ``compare`` estimates it.

        The response is linear in x(0), so x(0) comes from linear least squares.

        Args:
            u: the record's input, detrended, in the units of the model's input.
            y: the record's output, detrended, in the units of the model's output; as long as u.
            horizon: "one_step" fits the one-step prediction, "simulation" the simulated output.
        """
        zeros, no_signal = np.zeros(self.order), np.zeros_like(y, dtype=float)
        unit_states = np.eye(self.order)
        if horizon == "one_step":
            base = self.predict(u, y, zeros)
            columns = [self.predict(no_signal, no_signal, x0) for x0 in unit_states]
        elif horizon == "simulation":
            base = self.simulate(u, zeros)
            columns = [self.simulate(no_signal, x0) for x0 in unit_states]
        else:
            raise ValueError(f"horizon = {horizon!r}: expected 'one_step' or 'simulation'")
        solution, *_ = np.linalg.lstsq(np.column_stack(columns), y - base, rcond=None)
        return solution
