"""Tracking and estimation figures of a closed-loop run, from sampled signals."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class TrackingMetrics:
    """How well the head followed its reference after the last reference step.

    Errors are judged over a fixed window, from ``evaluation_delay_s`` after the last step to the
    end, whether or not the head settled: a metric must not depend on what it judges.

    Attributes:
        settled: whether the head was inside the tolerance band at the end.
        settle_time_s: from the last step to the last time the head came back inside the band
            (None if it ends outside).
        window_start_s, window_end_s: the window the figures below are taken over (s).
        rms_error_m, p95_abs_error_m, max_abs_error_m: |head - reference| over the window (m);
            None when the run ends before the window has two samples.
        time_within_tolerance_fraction: the fraction of the window's time the head was within
            the band, when a beam could be on (samples are evenly spaced); None as above.
        overshoot_m: largest excursion past the final reference in the step's direction (m); 0 for
            none, None when the reference never steps.
        final_error_m: head - reference at the last sample (m).
    """

    settled: bool
    settle_time_s: float | None
    window_start_s: float
    window_end_s: float
    rms_error_m: float | None
    p95_abs_error_m: float | None
    max_abs_error_m: float | None
    time_within_tolerance_fraction: float | None
    overshoot_m: float | None
    final_error_m: float


def tracking_metrics(
    times_s: np.ndarray,
    head_m: np.ndarray,
    reference_m: np.ndarray,
    *,
    last_step_time_s: float,
    tolerance_m: float,
    evaluation_delay_s: float,
) -> TrackingMetrics:
    """Settling, error statistics over a fixed window, and overshoot after the last step.

    Args:
        times_s: sample times (s), increasing and evenly spaced.
        head_m: true head height at those times (m).
        reference_m: reference at those times (m).
        last_step_time_s: when the reference last changed (0 if it never did).
        tolerance_m: the clinical band (m).
        evaluation_delay_s: the window starts this long after the last step (s).
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
    # "not inside" rather than "outside": a NaN error must not count as inside.
    inside = np.abs(error) <= tolerance_m
    outside_after = ~inside[after_indices]
    settled = not outside_after[-1]
    settle_time_s = None
    if settled:
        last_outside = np.flatnonzero(outside_after)
        back_inside = after_indices[last_outside[-1] + 1] if last_outside.size else after_indices[0]
        settle_time_s = float(times_s[back_inside]) - last_step_time_s

    window_start_s = last_step_time_s + evaluation_delay_s
    in_window = times_s >= window_start_s
    window = np.abs(error[in_window])
    figures = (
        (
            float(np.sqrt(np.mean(window**2))),
            float(np.percentile(window, 95)),
            float(window.max()),
            float(np.mean(inside[in_window])),
        )
        # One sample is no window: a run that ends as its window starts has nothing to judge.
        if window.size >= 2
        else (None, None, None, None)
    )

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
        window_start_s=window_start_s,
        window_end_s=float(times_s[-1]),
        rms_error_m=figures[0],
        p95_abs_error_m=figures[1],
        max_abs_error_m=figures[2],
        time_within_tolerance_fraction=figures[3],
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
