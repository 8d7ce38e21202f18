"""Filtering a signal through N(q) / D(q), the one filter identification runs.

It computes what ``scipy.signal.lfilter(numerator, denominator, signal, zi=initial_state)[0]``
computes, initial state included, because importing scipy.signal takes most of a second (it
imports scipy.stats) and `maskless identify` has a second in all (issue 14). Normalised to
d0 = 1 as lfilter normalises it, D(q) y = N(q) x is a unit lower-triangular banded Toeplitz
system in y, and BLAS's banded triangular solve (``dtbsv``) is forward substitution through it:
the filter's recursion, in compiled code (123 µs for 20,000 samples of a second-order D here,
lfilter 139 µs). The numerator's part is numpy's convolution.

An initial state ``zi`` in lfilter's transposed direct form adds ``zi[k]`` to the right-hand side
of step k (its k-th entry reaches the output k samples later), so it enters the first entries.
"""

import functools

import numpy as np
import scipy.linalg.blas


def filter_signal(numerator, denominator, signal: np.ndarray, initial_state=None) -> np.ndarray:
    """The output of N(q) / D(q) driven by ``signal``, as scipy.signal.lfilter's.

    Args:
        numerator: N's coefficients, n0 + n1 q⁻¹ + ...
        denominator: D's coefficients, d0 + d1 q⁻¹ + ..., d0 not 0.
        signal: the 1-D input.
        initial_state: lfilter's ``zi`` (max(len N, len D) - 1 values), or None for rest.
    """
    numerator = np.atleast_1d(np.asarray(numerator, float))
    denominator = np.atleast_1d(np.asarray(denominator, float))
    signal = np.asarray(signal, float)
    if signal.ndim != 1:
        raise ValueError(f"signal: expected a 1-D array, got shape {signal.shape}")
    if numerator.ndim != 1 or numerator.size == 0:
        raise ValueError(f"numerator = {numerator}: expected a 1-D array of coefficients")
    if denominator.ndim != 1 or denominator.size == 0 or denominator[0] == 0.0:
        raise ValueError(f"denominator = {denominator}: expected a leading coefficient not 0")
    numerator, denominator = numerator / denominator[0], denominator / denominator[0]
    state_size = max(numerator.size, denominator.size) - 1
    samples = signal.size
    drive = np.convolve(signal, numerator)[:samples] if samples else np.zeros(0)
    if initial_state is not None:
        initial_state = np.asarray(initial_state, float).ravel()
        if initial_state.size != state_size:
            raise ValueError(
                f"initial_state: expected {state_size} values, got {initial_state.size}"
            )
        head = min(state_size, samples)
        drive[:head] += initial_state[:head]
    if denominator.size == 1 or samples == 0:
        return drive
    order = denominator.size - 1
    band = _band(denominator.tobytes(), samples)
    return scipy.linalg.blas.dtbsv(order, band, drive, trans=1, diag=1, overwrite_x=1)


# A search filters several signals through each denominator it tries (the prediction and each
# column of its Jacobian), and building the band takes half as long as the solve.
@functools.lru_cache(maxsize=4)
def _band(denominator_bytes: bytes, samples: int) -> np.ndarray:
    """D's Toeplitz matrix as BLAS's banded storage of the transpose of an upper-triangular one.

    The band's last row is the (unit) diagonal, and row k - i holds D's i-th coefficient in
    every column. Read-only: it is shared between calls.
    """
    denominator = np.frombuffer(denominator_bytes)
    band = np.repeat(denominator[np.newaxis, ::-1], samples, axis=0).T
    band.flags.writeable = False
    return band
