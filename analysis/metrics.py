"""Tracking and estimation figures of a closed-loop run, from sampled signals."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrackingMetrics:
    """How well the head followed its reference after the last reference step.

    Attributes:
        settled: whether the head entered the tolerance band and stayed there to the end.
        settle_time_s: time from the last step to entering the band for good (None if never).
        evaluation_start_s: errors below are measured from here to the end (s).
        rms_error_m, p95_abs_error_m, max_abs_error_m: |head - reference| over that window (m).
        overshoot_m: largest excursion past the final reference in the step's direction (m); 0 for
            none, None when the reference never steps.
        final_error_m: head - reference at the last sample (m).
    """

    settled: bool
    settle_time_s: float | None
    evaluation_start_s: float
    rms_error_m: float
    p95_abs_error_m: float
    max_abs_error_m: float
    overshoot_m: float | None
    final_error_m: float


def tracking_metrics(
    times_s: np.ndarray,
    head_m: np.ndarray,
    reference_m: np.ndarray,
    *,
    last_step_time_s: float,
    tolerance_m: float,
    unsettled_evaluation_delay_s: float,
) -> TrackingMetrics:
    """Settling, error statistics and overshoot after the last reference step.

    Args:
        times_s: sample times (s), increasing.
        head_m: true head height at those times (m).
        reference_m: reference at those times (m).
        last_step_time_s: when the reference last changed (0 if it never did).
        tolerance_m: the settling band (m).
        unsettled_evaluation_delay_s: if the head never settles, errors are measured from this long
            after the last step (or from the step, when the run ends sooner).
    """
    times_s, head_m, reference_m = (np.asarray(a, float) for a in (times_s, head_m, reference_m))
    if not len(times_s) == len(head_m) == len(reference_m) or len(times_s) == 0:
        raise ValueError(
            "tracking_metrics: times_s, head_m and reference_m must be non-empty and of equal "
            f"length, got {len(times_s)}, {len(head_m)}, {len(reference_m)}"
        )
    error = head_m - reference_m
    after = times_s >= last_step_time_s
    if not after.any():
        raise ValueError(
            f"tracking_metrics: no samples after the last step at {last_step_time_s} s "
            f"(samples end at {times_s[-1]} s)"
        )
    after_indices = np.flatnonzero(after)
    # "not inside" rather than "outside": a NaN error must not count as settled.
    outside = ~(np.abs(error[after_indices]) <= tolerance_m)
    settled = not outside[-1]
    if settled:
        last_outside = np.flatnonzero(outside)
        first_inside = (
            after_indices[last_outside[-1] + 1] if last_outside.size else after_indices[0]
        )
        evaluation_start_s = float(times_s[first_inside])
        settle_time_s = evaluation_start_s - last_step_time_s
    else:
        settle_time_s = None
        evaluation_start_s = last_step_time_s + unsettled_evaluation_delay_s
        if evaluation_start_s > times_s[-1]:
            # A run too short for the delay: judge everything after the step.
            evaluation_start_s = last_step_time_s
    window = np.abs(error[times_s >= evaluation_start_s])

    overshoot_m = None
    before = times_s < last_step_time_s
    if before.any():
        step = reference_m[after_indices[0]] - reference_m[np.flatnonzero(before)[-1]]
        if step != 0:
            beyond = np.sign(step) * (head_m[after] - reference_m[after])
            overshoot_m = float(max(0.0, beyond.max()))
    return TrackingMetrics(
        settled=bool(settled),
        settle_time_s=settle_time_s,
        evaluation_start_s=evaluation_start_s,
        rms_error_m=float(np.sqrt(np.mean(window**2))),
        p95_abs_error_m=float(np.percentile(window, 95)),
        max_abs_error_m=float(window.max()),
        overshoot_m=overshoot_m,
        final_error_m=float(error[-1]),
    )


def estimate_error_std_m(
    times_s: np.ndarray, estimate_m: np.ndarray, truth_m: np.ndarray, start_s: float
) -> float:
    """Std of (estimate - truth) from ``start_s`` on (m): a track's noise, not its bias."""
    times_s = np.asarray(times_s, float)
    window = times_s >= start_s
    return float(np.std(np.asarray(estimate_m)[window] - np.asarray(truth_m)[window]))
