"""N4SID-family subspace identification (PO-MOESP) of single-output models with m inputs.

Past and future block-Hankel matrices of u and y are compressed by one Cholesky factorisation of
their Gram matrix (the LQ decomposition of Verhaegen's PO-MOESP, computed as L Lᵀ = D Dᵀ); the
SVD of the future outputs' part that the past explains gives the extended observability matrix,
whose shift invariance gives A. In the observer canonical form, which only needs A's
characteristic polynomial, B and x(0) enter the output linearly and come from least squares, and
the innovations gain K from a small prediction-error fit with A and B held (which starts from, and
keeps, a stable predictor). With m inputs (u of shape (N, m)) each block row of inputs holds m
rows, one per input, and B (n x m) comes from the same least squares with one set of columns per
input; a single input (u 1-D) builds exactly the matrices it always did.

The horizons are chosen from the data. The past horizon p must span the one-step predictor's
memory, so that the past determines the state (PO-MOESP is biased by the predictor's transient
over p samples): it is the ARX(p, p) order that Schwarz's criterion (BIC) picks,
N log(RSS_p / N) + 2p log N, among p = n + 1 .. ``LONGEST_PAST_HORIZON`` (fewer when the record is
short); the regressions for every p come from the same Gram matrix, so the choice costs no pass
over the data (with m inputs an ARX(p, p) has (m + 1) p coefficients, the penalty's count). BIC
rather than AIC: AIC's penalty does not grow with N, so on long records it picks long pasts that
add variance. The future horizon f = 2n + 2 need only make the
observability matrix taller than n (twice n, plus two rows, leaves its shift-invariance least
squares overdetermined); longer futures add variance, not information.
``benchmarks/subspace_horizon.py`` compares the pole errors with the former fixed horizon
max(2n + 2, 10).
"""

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
import scipy.linalg

from maskless.analysis.identification.innovations_model import (
    InnovationsModel,
    delayed_copies,
    impulse_response,
    samples_before_growth,
)
from maskless.analysis.identification.linear_filter import filter_signal
from maskless.analysis.identification.prediction_error import (
    check_order_and_shapes,
    estimate_noise_model,
)

# The longest past horizon the criterion considers: it bounds the Gram matrix at 2 (30 + f) rows.
LONGEST_PAST_HORIZON = 30
# Hankel columns (equations) per block row of data, at least: the least squares behind the
# projection stays well overdetermined.
_COLUMNS_PER_ROW = 5
HORIZON_RULE = (
    "past: the ARX(p, p) order BIC picks, n + 1 <= p <= 30; future: 2n + 2 (analysis/"
    "identification/subspace.py)"
)


class SubspaceFit(NamedTuple):
    """What ``estimate_n4sid`` returns (a tuple, so ``estimate_n4sid(...)[0]`` is the model).

    Attributes:
        model: the identified model.
        singular_values: those of the projected future outputs; they show how many states the
            data support.
        past_horizon: p, block rows of past data.
        future_horizon: f, block rows of future data.
    """

    model: InnovationsModel
    singular_values: np.ndarray
    past_horizon: int
    future_horizon: int


def future_horizon_for(order: int) -> int:
    """The future horizon, 2n + 2 block rows (see the module docstring)."""
    return 2 * order + 2


def estimate_n4sid(
    u: np.ndarray,
    y: np.ndarray,
    order: int,
    sample_period_s: float,
    *,
    past_horizon: int | None = None,
    future_horizon: int | None = None,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
) -> SubspaceFit:
    """A model of ``order`` by PO-MOESP.

    Args:
        u: the record's input, detrended: (N,), or (N, m) for m inputs (each column one input).
        y: the record's output, detrended, 1-D, N samples.
        order: n, the number of states.
        sample_period_s: Ts (s).
        past_horizon: p; by default chosen from the data (module docstring).
        future_horizon: f; by default 2n + 2.
        estimate_initial_state: estimate x(0) too; otherwise x(0) = 0.
        progress: called as progress(evaluations, cost) during the noise model's search.
    """
    check_order_and_shapes(u, y, order)
    m = 1 if u.ndim == 1 else u.shape[1]
    f = future_horizon_for(order) if future_horizon is None else future_horizon
    if f <= order or (past_horizon is not None and past_horizon <= order):
        raise ValueError(
            f"order {order} with past horizon {past_horizon} and future horizon {f}: need "
            "1 <= order < each horizon"
        )
    longest = past_horizon or _longest_past(y.size, order, f, m)
    if y.size - longest - f + 1 < _COLUMNS_PER_ROW * (m + 1) * (longest + f):
        raise ValueError(
            f"{y.size} samples are too few for past horizon {longest} and future horizon {f}"
        )
    gram, columns = _hankel_gram(u, y, longest, f)
    p = past_horizon or _past_horizon_by_bic(gram, columns, order, longest, f, m)
    lower = _lq_factor(gram, _rows(longest, p, f, m))
    # The part of the future outputs that the past (inputs and outputs) explains.
    projected = lower[m * f + (m + 1) * p :, m * f : m * f + (m + 1) * p]
    left, singular_values, _ = np.linalg.svd(projected, full_matrices=False)
    observability = left[:, :order] * np.sqrt(singular_values[:order])
    # Shift invariance: the observability matrix without its last row, times A, is the one without
    # its first row. Only A's characteristic polynomial is kept; C is implied by the canonical form.
    A, *_ = np.linalg.lstsq(observability[:-1], observability[1:], rcond=None)
    a = np.real(np.poly(A))[1:]
    b, x0 = _input_gain_and_initial_state(u, y, a, estimate_initial_state)
    deterministic = InnovationsModel(
        a=a, b=b, k=np.zeros(order), sample_period_s=sample_period_s, initial_state=x0
    )
    model = estimate_noise_model(deterministic, u, y, estimate_initial_state, progress)
    return SubspaceFit(model, singular_values, p, f)


def minimum_samples(order: int, inputs: int = 1) -> int:
    """The fewest samples ``estimate_n4sid`` accepts for ``order`` with its default horizons.

    Args:
        order: n.
        inputs: m, the number of inputs.
    """
    # Past horizon n + 1 and columns = samples - p - f + 1 >= _COLUMNS_PER_ROW (m + 1) (p + f).
    return (order + 1 + future_horizon_for(order)) * (1 + (inputs + 1) * _COLUMNS_PER_ROW) - 1


def _longest_past(samples: int, order: int, future: int, inputs: int = 1) -> int:
    """The longest past horizon the record supports (at most LONGEST_PAST_HORIZON)."""
    per_row = 1 + (inputs + 1) * _COLUMNS_PER_ROW
    supported = (samples + 1 - future * per_row) // per_row
    longest = min(LONGEST_PAST_HORIZON, supported)
    if longest <= order:
        raise ValueError(
            f"{samples} samples are too few for an order-{order} subspace fit: need at least "
            f"{(order + 1 + future) * per_row - 1}"
        )
    return longest


def _hankel_gram(u, y, longest: int, future: int) -> tuple[np.ndarray, int]:
    """D Dᵀ for the rows [future u (m f), past u (m P), past y (P), future y (f)], and D's columns.

    Each block row of inputs holds the m inputs in turn (u 1-D is one input). Past rows run oldest
    to newest, so the newest p of them serve any past horizon p <= P. Row r is a signal from
    sample offset o_r, so entry (r, s) is a sum of lagged products over a window,
    Σ_c a[o_r + c] b[o_s + c], read from the running sums of a[t] b[t + o_s - o_r]: no BLAS call,
    whose threads, on a busy machine, made the 80-row product D Dᵀ many times slower.
    """
    columns = y.size - longest - future + 1
    span = longest + future
    inputs = ["u"] if u.ndim == 1 else [f"u{i}" for i in range(u.shape[1])]
    signals = {"y": y, **dict(zip(inputs, [u] if u.ndim == 1 else list(u.T), strict=True))}
    m = len(inputs)
    offsets = np.concatenate(
        [
            np.repeat(np.arange(longest, span), m),
            np.repeat(np.arange(longest), m),
            np.arange(longest),
            np.arange(longest, span),
        ]
    )
    names = inputs * span + ["y"] * span
    # running[pair][lag, t]: Σ over t' < t of a[t'] b[t' + lag], zero outside the record. A
    # signal with itself needs only lags >= 0 (swap the rows for the others); a pair of signals
    # is kept once, in the order of ``order`` (swap the rows for the other).
    order = [*inputs, "y"]
    pairs = [((name, name), 0) for name in inputs] + [(("y", "y"), 0)]
    pairs += [((a, b), 1 - span) for i, a in enumerate(order) for b in order[i + 1 :]]
    running = {}
    for pair, lowest in pairs:
        first, second = signals[pair[0]], signals[pair[1]]
        padded = np.concatenate([np.zeros(-lowest), second, np.zeros(span - 1)])
        lagged = np.lib.stride_tricks.sliding_window_view(padded, second.size)
        sums = np.zeros((lagged.shape[0], first.size + 1))
        np.cumsum(first * lagged, axis=1, out=sums[:, 1:])
        running[pair] = (sums, lowest)
    gram = np.empty((offsets.size, offsets.size))
    for r in range(offsets.size):
        for s in range(r, offsets.size):
            (name_r, offset_r), (name_s, offset_s) = (names[r], offsets[r]), (names[s], offsets[s])
            if (name_r, name_s) not in running:  # the pair is kept the other way round
                (name_r, offset_r), (name_s, offset_s) = (name_s, offset_s), (name_r, offset_r)
            start, lag = offset_r, offset_s - offset_r
            if name_r == name_s and lag < 0:
                start, lag = offset_s, -lag
            sums, lowest = running[(name_r, name_s)]
            window = sums[lag - lowest]
            gram[r, s] = gram[s, r] = window[start + columns] - window[start]
    return gram, columns


def _rows(longest: int, past: int, future: int, inputs: int = 1) -> np.ndarray:
    """Indices into the Gram matrix of [future u, the newest ``past`` u, y, future y].

    Each block row of u holds ``inputs`` rows.
    """
    f, P, m = future, longest, inputs
    return np.concatenate(
        [
            np.arange(m * f),
            np.arange(m * (f + P - past), m * (f + P)),
            np.arange(m * (f + P) + P - past, m * (f + P) + P),
            np.arange(m * (f + P) + P, m * (f + P) + P + f),
        ]
    )


def _lq_factor(gram: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """L with L Lᵀ = the Gram matrix of ``rows``: the L of the LQ decomposition of those rows.

    A Gram matrix that is only semi-definite (an input that does not excite every row) has no
    Cholesky factor; its eigen-decomposition then gives a factor of the same projections.
    """
    selected = gram[np.ix_(rows, rows)]
    try:
        return np.linalg.cholesky(selected)
    except np.linalg.LinAlgError:
        values, vectors = np.linalg.eigh(selected)
        factor = vectors * np.sqrt(np.maximum(values, 0.0))
        # An orthogonal change of columns keeps L Lᵀ; QR of Lᵀ makes L lower triangular again.
        return scipy.linalg.qr(factor.T, mode="r")[0].T


def _past_horizon_by_bic(
    gram, columns: int, order: int, longest: int, future: int, inputs: int = 1
) -> int:
    """The past horizon p whose ARX(p, p) predictor of y(t) BIC picks (module docstring).

    Each regression is of the first future output on the future inputs and the newest p past
    inputs and outputs: with the regressors ordered newest first, one Cholesky factor gives the
    residual of every p (the squared tail of the last row beyond the first m f + (m + 1) p
    columns, m = ``inputs``).
    """
    f, P, m = future, longest, inputs
    past_u = np.arange(m * (f + P) - 1, m * f - 1, -1).reshape(P, m)[:, ::-1]  # newest first
    past_y = np.arange(m * (f + P) + P - 1, m * (f + P) - 1, -1)
    newest_first = np.column_stack([past_u, past_y]).ravel()
    rows = np.concatenate([np.arange(m * f), newest_first, [m * (f + P) + P]])
    last = _lq_factor(gram, rows)[-1]
    residual = np.cumsum((last**2)[::-1])[::-1]  # residual[j]: regressors j.. left out
    candidates = np.arange(order + 1, P + 1)
    criterion = columns * np.log(residual[m * f + (m + 1) * candidates] / columns) + (
        m + 1
    ) * candidates * math.log(columns)
    return int(candidates[np.argmin(criterion)])


def _input_gain_and_initial_state(u, y, a, estimate_initial_state: bool):
    """B (and x(0)) by least squares for the poles ``a``: the output is linear in both.

    In the observer form the response to b_j is (q⁻ʲ / A) u and that to x0_j is the impulse
    response of 1/A delayed j samples; with m inputs each input has its n columns (b_ij from
    (q⁻ʲ / A) u_i), so B (n x m) comes out of the same least squares. For an unstable A only the
    samples before that response grows a millionfold enter, so no exploding response is evaluated.
    """
    order = a.size
    m = 1 if u.ndim == 1 else u.shape[1]
    denominator = np.concatenate([[1.0], a])
    used = samples_before_growth(np.roots(denominator), y.size)
    columns = []
    for column in [u] if u.ndim == 1 else list(u.T):
        through_a = filter_signal([1.0], denominator, column[:used])
        columns += delayed_copies(through_a, range(1, order + 1))
    if estimate_initial_state:
        columns += delayed_copies(impulse_response(denominator, used), range(order))
    solution, *_ = np.linalg.lstsq(np.column_stack(columns), y[:used], rcond=None)
    x0 = solution[m * order :] if estimate_initial_state else np.zeros(order)
    b = solution[:order] if u.ndim == 1 else solution[: m * order].reshape(m, order).T
    return b, x0
