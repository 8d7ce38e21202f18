"""Prediction-error identification (Eq. 11) of innovations-form models, and ARX by least squares.

``estimate_pem`` minimises the sum of squared one-step prediction errors over the observer-form
parameters (a, b, k) and, when asked, the initial state x(0): MATLAB's ``ssest``/``armax`` with
prediction focus. It starts from the ARX least-squares fit and runs scipy's Levenberg-Marquardt
(``least_squares(method="lm")``) with the exact Jacobian, which filters with 1/C(q). With m inputs
(u of shape (N, m)) b is n x m, one numerator per input over the common A(q); the ARX start
regresses on every input's lags and the Jacobian has a block per input.

The predictor is stable by construction. The search starts from a stable noise model: the start's
C(q) roots on or outside the unit circle are reflected inside (``stable_noise_polynomial``), so
the old failure, a start K = -0.5 a whose C(q) had roots at 1.02-1.16 and whose constant
residuals gave a zero Jacobian, cannot recur. It then stays inside: a trial step that makes C(q)
unstable costs far more than any accepted point, so Levenberg-Marquardt rejects it and shortens
the step.
"""

from collections.abc import Callable
from dataclasses import replace

import numpy as np
import scipy.optimize

from maskless.analysis.identification.innovations_model import (
    InnovationsModel,
    impulse_response,
)
from maskless.analysis.identification.linear_filter import filter_signal

# Residual given to the optimiser when a trial predictor is unstable or overflows, relative to the
# output's spread: far worse than any sensible model, yet finite.
_UNSTABLE_RESIDUAL_SCALE = 1e3
# Largest root magnitude of a noise model the search starts from (see stable_noise_polynomial).
_START_ROOT_RADIUS = 0.99


def estimate_arx(u: np.ndarray, y: np.ndarray, order: int, sample_period_s: float):
    """ARX(n, n, 1) by linear least squares: y(k) + a1 y(k-1) + ... = b1 u(k-1) + ... + e(k).

    With m inputs (u of shape (N, m)) every input's n lags are regressors, and b is (n, m).
    Returns an InnovationsModel with C(q) = 1 (k = -a) and zero initial state.
    """
    _check_record(u, y, order)
    n = order
    rows = y.size - n
    columns = u.reshape(u.shape[0], -1).T  # a single input is one column of its own
    regressors = np.column_stack(
        [-y[n - i : n - i + rows] for i in range(1, n + 1)]
        + [column[n - i : n - i + rows] for column in columns for i in range(1, n + 1)]
    )
    theta, *_ = np.linalg.lstsq(regressors, y[n:], rcond=None)
    a, b = theta[:n], theta[n:] if u.ndim == 1 else theta[n:].reshape(-1, n).T
    return InnovationsModel(
        a=a, b=b, k=-a, sample_period_s=sample_period_s, initial_state=np.zeros(n)
    )


def estimate_pem(
    u: np.ndarray,
    y: np.ndarray,
    order: int,
    sample_period_s: float,
    *,
    estimate_initial_state: bool = True,
    with_input: bool = True,
    initial_model: InnovationsModel | None = None,
    progress: Callable[[int, float], None] | None = None,
) -> InnovationsModel:
    """The innovations-form model of ``order`` that minimises the one-step prediction error.

    Args:
        u: the record's input, detrended: (N,), or (N, m) for m inputs (each column one input).
        y: the record's output, detrended, 1-D, N samples.
        order: n, the state dimension (= the ARMAX orders na = nb = nc, nk = 1).
        sample_period_s: Ts (s).
        estimate_initial_state: estimate x(0) too (MATLAB's InitialState 'estimate'); otherwise
            x(0) = 0.
        with_input: False fits the same structure with b = 0 (ARMA), the baseline that shows
            what the input adds.
        initial_model: where the search starts; by default the ARX fit with a noise model
            half-way to output error; either way its predictor is made stable first. The ARMA
            baseline starts from the full model with b = 0, so it answers "what does the input
            add to this model" rather than finding another local minimum.
        progress: called as progress(evaluations, cost) at each accepted step of the search.

    Returns:
        The model; its ``initial_state`` is the estimated x(0) of this record.
    """
    _check_record(u, y, order)
    n = order
    if initial_model is None:
        arx = estimate_arx(u, y, n, sample_period_s)
        # The noise model starts half-way between ARX (C = 1) and output error (C = A), so neither
        # extreme's local minimum is favoured. Half-way, C(z) = z^n + 0.5 (a1 z^(n-1) + ...), can
        # have roots outside the unit circle even when A's are inside; the search reflects them
        # inside before it starts (stable_noise_polynomial).
        x0_start = np.zeros(n)
        x0_start[0] = y[0]
        initial_model = InnovationsModel(
            a=arx.a,
            b=arx.b,
            k=-0.5 * arx.a,
            sample_period_s=sample_period_s,
            initial_state=x0_start,
        )
    free = ["a", "b", "k"] if with_input else ["a", "k"]
    start = (
        initial_model if with_input else replace(initial_model, b=np.zeros_like(initial_model.b))
    )
    if estimate_initial_state:
        free.append("initial_state")
    else:
        start = replace(start, initial_state=np.zeros(n))
    return _minimise_prediction_error(u, y, start, free, progress)


def estimate_noise_model(
    model: InnovationsModel,
    u: np.ndarray,
    y: np.ndarray,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
) -> InnovationsModel:
    """``model`` with its innovations gain K (and x(0) when asked) fitted by prediction error.

    Its dynamics A, B are held: this is how a subspace fit gets its noise model. The search
    starts from ``estimate_pem``'s half-way noise model, made stable, and keeps it stable.
    """
    _check_record(u, y, model.order)
    free = ["k", "initial_state"] if estimate_initial_state else ["k"]
    start = replace(
        model,
        k=-0.5 * model.a,
        initial_state=model.initial_state if estimate_initial_state else np.zeros(model.order),
    )
    return _minimise_prediction_error(u, y, start, free, progress)


def roots_mirrored_inside(tail) -> tuple[np.ndarray, np.ndarray]:
    """The roots of 1 + c1 q^-1 + ... + cn q^-n, and which lay on or outside the unit circle.

    Each root r with |r| >= 1 is replaced by its mirror 1 / conj(r): the polynomial's magnitude
    response keeps its shape (up to a constant). A root on the circle stays on it, so each caller
    pulls the mirrored roots inside by a margin of its own. Roots already inside are kept.
    Returns (complex roots, boolean mask of the roots that were on or outside the circle).
    """
    roots = np.roots(np.concatenate([[1.0], tail])).astype(complex)
    outside = np.abs(roots) >= 1.0
    roots[outside] = 1.0 / np.conj(roots[outside])
    return roots, outside


def stable_noise_polynomial(c: np.ndarray) -> np.ndarray:
    """C(q)'s coefficients c1..cn with every root on or outside the unit circle moved inside.

    Each such root is mirrored inside (``roots_mirrored_inside``: the same noise spectrum up to a
    constant, now with a stable predictor), then kept at least ``1 - _START_ROOT_RADIUS`` inside
    the circle so the predictor's transient decays within a few hundred samples.
    """
    roots, outside = roots_mirrored_inside(c)
    if not outside.any():
        return np.asarray(c, float)
    radius = np.minimum(np.abs(roots[outside]), _START_ROOT_RADIUS)
    roots[outside] = radius * np.exp(1j * np.angle(roots[outside]))
    return np.real(np.poly(roots))[1:]


def _minimise_prediction_error(u, y, start: InnovationsModel, free: list[str], progress):
    """Levenberg-Marquardt on the one-step errors over the named fields of ``start``.

    The search starts from a stable predictor and stays inside the stable-predictor region: a
    trial step whose C(q) has a root on or outside the unit circle costs far more than the start,
    so Levenberg-Marquardt rejects it and backs off to a shorter step. The Jacobian is
    evaluated only at accepted (stable) points, so it never vanishes on a constant residual.
    """
    start = replace(start, k=stable_noise_polynomial(start.c) - start.a)
    shapes = [getattr(start, name).shape for name in free]
    sizes = [getattr(start, name).size for name in free]
    # An m-input b (n, m) is packed input by input (column-major), as the Jacobian's blocks are.
    theta0 = np.concatenate([np.ravel(getattr(start, name), order="F") for name in free])
    # Finite and far above the start's cost: an unstable trial step can never be accepted.
    start_error = y - start.predict(u, y)
    scale = max(float(np.std(y)), float(np.sqrt(np.mean(start_error**2)))) or 1.0
    evaluations = [0]
    # The last stable point's errors: the Jacobian is asked for at the point just evaluated.
    last = {"theta": None, "error": None}

    def unpack(theta):
        values, offset = {}, 0
        for name, size, shape in zip(free, sizes, shapes, strict=True):
            values[name] = np.reshape(theta[offset : offset + size], shape, order="F")
            offset += size
        return replace(start, **values)

    def residuals(theta):
        model = unpack(theta)
        evaluations[0] += 1
        if np.any(np.abs(model.predictor_poles()) >= 1.0):
            return np.full(y.size, _UNSTABLE_RESIDUAL_SCALE * scale)
        with np.errstate(over="ignore", invalid="ignore"):
            error = y - model.predict(u, y)
        if not np.all(np.isfinite(error)):
            return np.full(y.size, _UNSTABLE_RESIDUAL_SCALE * scale)
        last.update(theta=theta.copy(), error=error)
        return error

    def jacobian(theta):
        # Called once per accepted step, at the point the search has moved to.
        model = unpack(theta)
        if np.array_equal(theta, last["theta"]):
            error = last["error"]
        else:
            error = y - model.predict(u, y)
        if progress is not None:
            progress(evaluations[0], float(error @ error))
        return _error_jacobian(model, u, y, error, free)

    solution = scipy.optimize.least_squares(
        residuals, theta0, jac=jacobian, method="lm", x_scale="jac"
    )
    return unpack(solution.x)


def _error_jacobian(model: InnovationsModel, u, y, error, free: list[str]) -> np.ndarray:
    """d(y - ŷ)/dθ of the one-step errors ``error`` = y - ŷ, exactly, by filtering with 1/C(q).

    From C ŷ = B u + K y + (x(0) entering at samples 0..n-1) with c = a + k: dε/da_i = q⁻ⁱ ŷ / C,
    dε/db_i = -q⁻ⁱ u / C, dε/dk_i = -q⁻ⁱ ε / C, and dε/dx0_j is minus the impulse response of
    1/C delayed j samples. One filter per free field replaces the 2 (d + 1) of a finite-difference
    Jacobian. An m-input b has m blocks, dε/db_ij = -q⁻ⁱ u_j / C, input by input.
    """
    n, samples = model.order, y.size
    denominator = np.concatenate([[1.0], model.c])
    # Each free field's derivative is its source filtered by 1/C; only the free ones are filtered.
    inputs = -u if u.ndim == 1 else list(-u.T)
    sources = {"a": [y - error], "b": [inputs] if u.ndim == 1 else inputs, "k": [-error]}
    # The coefficients act one sample later than x(0): q⁻¹..q⁻ⁿ against delays 0..n-1.
    first_delay = {"a": 1, "b": 1, "k": 1, "initial_state": 0}
    blocks = [(name, source) for name in free for source in sources.get(name, [None])]
    # Built transposed, so the returned Jacobian is in the column-major order MINPACK reads.
    transposed = np.zeros((n * len(blocks), samples))
    for block, (name, source) in enumerate(blocks):
        if name == "initial_state":
            signal = -impulse_response(denominator, samples)
        else:
            signal = filter_signal([1.0], denominator, source)
        for i in range(n):
            delay = first_delay[name] + i
            transposed[block * n + i, delay:] = signal[: samples - delay]
    return transposed.T


def estimate_ar(y: np.ndarray, order: int, sample_period_s: float) -> InnovationsModel:
    """AR(n) by least squares, y(k) + a1 y(k-1) + ... = e(k): ARX without its input.

    It is the baseline an ARX model must beat.
    """
    return replace(estimate_arx(np.zeros_like(y), y, order, sample_period_s), b=np.zeros(order))


def parameter_count(
    order: int,
    *,
    with_input: bool,
    with_noise_model: bool,
    estimated_initial_state: bool,
    inputs: int = 1,
) -> int:
    """d, the free parameters of a fit: n each for a, k and x(0), n per input for b.

    b counts with an input (n for each of ``inputs``), k with a noise model (ARX has none) and
    x(0) when it is estimated.
    """
    return order * (1 + inputs * with_input + with_noise_model + estimated_initial_state)


def check_order_and_shapes(u, y, order) -> None:
    """Raises ValueError unless order is a positive integer, y 1-D and u has one row per y."""
    if not isinstance(order, int | np.integer) or order < 1:
        raise ValueError(f"order = {order!r}: expected a positive integer")
    if y.ndim != 1 or u.ndim not in (1, 2) or u.shape[0] != y.size or 0 in u.shape[1:]:
        raise ValueError(
            f"u and y must be of one length, y 1-D and u 1-D or one column per input, got "
            f"{u.shape} and {y.shape}"
        )


def _check_record(u, y, order):
    check_order_and_shapes(u, y, order)
    if y.size < 10 * order:
        raise ValueError(f"{y.size} samples are too few for an order-{order} model")
