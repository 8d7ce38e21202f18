"""N4SID-family subspace identification (PO-MOESP) of single-input, single-output models.

Past and future block-Hankel matrices of u and y are compressed by one QR factorisation (the LQ
decomposition of Verhaegen's PO-MOESP); the SVD of the future outputs' part that the past explains
gives the extended observability matrix, whose shift invariance gives A. In the observer canonical
form, which only needs A's characteristic polynomial, B and x(0) enter the output linearly and come
from least squares, and the innovations gain K from a small prediction-error fit with A and B held.
The result is expressed in the observer canonical form of ``InnovationsModel``.

The horizon (block rows) defaults to max(2n + 2, 10): long enough for the observability matrix to
reveal n states, short enough that the Hankel matrices stay 4·horizon rows high, so a 100,000
sample record costs one QR of a 100,000 x 40 matrix.
"""

from collections.abc import Callable

import numpy as np
import scipy.linalg

from maskless.analysis.identification.innovations_model import InnovationsModel
from maskless.analysis.identification.prediction_error import estimate_noise_model


def default_horizon(order: int) -> int:
    """Block rows of the past and future Hankel matrices."""
    return max(2 * order + 2, 10)


def _block_hankel(signal: np.ndarray, rows: int, columns: int) -> np.ndarray:
    """Rows x columns Hankel matrix, entry (r, c) = signal[r + c] (a view, no copy)."""
    windows = np.lib.stride_tricks.sliding_window_view(signal, columns)
    return windows[:rows]


def estimate_n4sid(
    u: np.ndarray,
    y: np.ndarray,
    order: int,
    sample_period_s: float,
    horizon: int | None = None,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
) -> tuple[InnovationsModel, np.ndarray]:
    """A model of ``order`` by PO-MOESP.

    Returns:
        (model, singular_values): the singular values of the projected future outputs, which show
        how many states the data support.
    """
    horizon = default_horizon(order) if horizon is None else horizon
    if order < 1 or horizon <= order:
        raise ValueError(f"order {order} with horizon {horizon}: need 1 <= order < horizon")
    if u.shape != y.shape or u.ndim != 1:
        raise ValueError(f"u and y must be 1-D and of one length, got {u.shape} and {y.shape}")
    columns = y.size - 2 * horizon + 1
    if columns < 10 * horizon:
        raise ValueError(f"{y.size} samples are too few for horizon {horizon}")
    i = horizon
    hankel_u = _block_hankel(u, 2 * i, columns)
    hankel_y = _block_hankel(y, 2 * i, columns)
    # Rows: future inputs, past inputs, past outputs, future outputs.
    data = np.vstack([hankel_u[i:], hankel_u[:i], hankel_y[:i], hankel_y[i:]])
    lower = scipy.linalg.qr(data.T, mode="r", check_finite=False)[0][: 4 * i].T
    # The part of the future outputs that the past (inputs and outputs) explains.
    projected = lower[3 * i :, i : 3 * i]
    left, singular_values, _ = np.linalg.svd(projected, full_matrices=False)
    observability = left[:, :order] * np.sqrt(singular_values[:order])
    # Shift invariance: the observability matrix without its last row, times A, is the one without
    # its first row. Only A's characteristic polynomial is kept; C is implied by the canonical form.
    A, *_ = np.linalg.lstsq(observability[:-1], observability[1:], rcond=None)

    # Observer canonical form: a from A's characteristic polynomial; then B and x(0) are linear.
    a = np.real(np.poly(A))[1:]
    shell = InnovationsModel(
        a=a,
        b=np.zeros(order),
        k=np.zeros(order),
        sample_period_s=sample_period_s,
        initial_state=np.zeros(order),
    )
    unit = np.eye(order)
    columns_b = [
        InnovationsModel(
            a=a,
            b=unit[j],
            k=np.zeros(order),
            sample_period_s=sample_period_s,
            initial_state=np.zeros(order),
        ).simulate(u)
        for j in range(order)
    ]
    columns_x0 = (
        [shell.free_response(y.size, unit[j]) for j in range(order)]
        if (estimate_initial_state)
        else []
    )
    solution, *_ = np.linalg.lstsq(np.column_stack(columns_b + columns_x0), y, rcond=None)
    b = solution[:order]
    x0 = solution[order:] if estimate_initial_state else np.zeros(order)
    deterministic = InnovationsModel(
        a=a, b=b, k=np.zeros(order), sample_period_s=sample_period_s, initial_state=x0
    )
    model = estimate_noise_model(deterministic, u, y, estimate_initial_state, progress)
    return model, singular_values
