"""Where each hold of a record settled: a fixed time after it began, or later where it shows it.

``settled_curve.settled_levels`` counts a hold as settled a fixed time after it began: four time
constants of the slowest pole of the record's ARX model (``hammerstein._settle_samples``). That
time is one number for a plant whose approach depends on the step: the pneumatic plant settles
(to 2 %) in a median 7.7 s over a record's long holds, and in 33 s after the inlet's full opening,
an 18 mm step. It is also read off a model that a record's noise shapes: on the cameras' fused
height of seed 2 of ``benchmarks/hammerstein.py`` (issue 14) it came out 31 s, on the plant's
noise-free true height 18 s, and there two inlet holds still rising entered as levels (their
means 0.15 and 0.58 mm under their holds' ends) and put the inlet's starting current 11.7 mA off.

Here a hold settles at the fixed time, or later where its own output shows it had not:

- **Its final value** is the mean of its last quarter (at least ``min_tail_samples``).
- **The band** is the larger of 2 % of its step (the fixed rule's e^-4 of the step left) and
  five standard deviations of the record's output averaged over a window: the noise a settled
  output still shows, at its largest. A minute's hold holds some thirty independent window
  averages, whose largest passes three deviations on about one hold in twelve of white noise,
  and the cameras' noise has heavier tails (quantisation, dropouts). At three, the rule moved
  1-6 levels of each of five camera records (seeds 2, 4, 28, 58 and 63 of the benchmark's
  design) later or out; at five, none; on their true heights, as many at either.
- **The window** is a thirty-second of the fixed settling time, short against the plant's
  approach and long against the cameras' noise (about 1 s on the benchmark's camera records,
  whose fixed settling times are 31-41 s). The noise is read from the median change of that
  average over one window, over the whole record, so the transients (a minority of samples) do
  not inflate it.
- **Where its output settled** is the sample after the last window average outside the band.
- **Never before the fixed time**: within the noise band an approach is hidden, not over. Read
  from the holds alone (no floor; a band of three deviations), the outlet's small steps counted
  as settled from their first sample, their approaches entered their means, and on the cameras'
  records (seeds 0-63 at 60 mA) the outlet's start came within 5 mA on 54, not 60, and its
  curve within 10 % on 59, not 62.
- **A hold still moving** is left out: one whose tail (from there to its end) trends by more than
  the band over its length (a least-squares line). Its final value is then below (above) where
  it would go, and the band around it says nothing.
- A hold whose tail is shorter than ``min_tail_samples`` is left out. The record's first hold,
  with no output before it, takes its step from its own first window.

The fixed time itself can be read too slow: the cameras' fused height wanders slowly, and the
ARX pole can follow it. ``settling_from_holds`` times the record's large steps from their own
approaches (an exponential tail fitted to each, its final value included), and
``hammerstein`` takes the shorter of the two.
"""

import numpy as np

from maskless.analysis.identification.settled_curve import (
    SettledLevels,
    hold_runs,
    levels_from,
)

# A hold's output has settled within this fraction of its step (e^-4, the fixed rule's 2 %) ...
_STEP_FRACTION = 0.02
# ... or within this many standard deviations of the noise of a window's average: the band holds
# a settled hold's largest average, not a typical one (see the module docstring).
_NOISE_DEVIATIONS = 5.0
# The averaging window, as a fraction of the fixed settling time.
_WINDOW_OF_SETTLE = 1.0 / 32.0
# A hold's final value is the mean of this share of it, at its end.
_FINAL_SHARE = 0.25
# The median absolute deviation of a normal variable times this is its standard deviation.
_MAD_TO_STD = 1.4826


def settled_levels_by_holds(u, y, settle_samples: int, min_tail_samples: int) -> SettledLevels:
    """Each hold's mean output from where it settled (see the module docstring) to its end.

    Args:
        u: (N, inputs) the currents; a hold is a run of unchanged currents (``hold_runs``).
        y: (N,) the output.
        settle_samples: the fixed settling time: the earliest a hold settles, and what sets
            the averaging window.
        min_tail_samples: the fewest settled samples a level averages.
    """
    u, y = np.asarray(u), np.asarray(y, dtype=float)
    starts, ends = hold_runs(u)
    window = max(1, int(settle_samples * _WINDOW_OF_SETTLE))
    average = window_averages(y, window)
    noise = window_noise(average, window)
    tail_least = max(1, min_tail_samples)
    kept, firsts = [], []
    for hold, (first, end) in enumerate(zip(starts, ends, strict=True)):
        settled = _settled_from(y, average, first, end, window, noise, tail_least, settle_samples)
        if settled is not None:
            kept.append(hold)
            firsts.append(settled)
    return levels_from(u, y, (starts, ends), kept, firsts)


def window_averages(y, window: int) -> np.ndarray:
    """(N,) the mean of ``y``'s last ``window`` samples at each sample; NaN for the first few."""
    averages = np.full(y.size, np.nan)
    averages[window - 1 :] = np.lib.stride_tricks.sliding_window_view(y, window).mean(axis=1)
    return averages


def window_noise(averages, window: int) -> float:
    """The standard deviation of a window's average of the noise, from its changes.

    Two averages a window apart share no sample, so their difference has twice the variance of
    one: the median absolute change over the record, over sqrt(2), as a robust deviation.
    """
    changes = averages[window:] - averages[:-window]
    changes = changes[np.isfinite(changes)]
    if changes.size == 0:
        return 0.0
    return float(_MAD_TO_STD * np.median(np.abs(changes)) / np.sqrt(2.0))


def _settled_from(y, average, first, end, window, noise, tail_least, settle_samples):
    """The sample the hold ``first``-``end`` settled at, or None if it did not (see above)."""
    if end - first < tail_least + window:
        return None
    final = _final_value(y, first, end, tail_least)
    # The step from the window before the hold; the record's first hold, with none before,
    # from its own first window.
    before = y[first - window : first] if first >= window else y[first : first + window]
    step = final - before.mean()
    band = max(_STEP_FRACTION * abs(step), _NOISE_DEVIATIONS * noise)
    # The first average that reads only the hold's own samples.
    checked = np.arange(first + window - 1, end)
    outside = np.flatnonzero(np.abs(average[checked] - final) > band)
    settled = first + settle_samples
    if outside.size:
        settled = max(settled, int(checked[outside[-1]]) + 1)
    tail = y[settled:end]
    if tail.size < tail_least:
        return None
    if tail.size > 1 and abs(np.polyfit(np.arange(tail.size), tail, 1)[0]) * tail.size > band:
        return None
    return settled


# A large step's approach is timed from where it is within this share of its step (clear of the
# cameras' noise) on: its output there is fitted as an exponential tail, final value included,
# and its settling time is where that tail is within _STEP_FRACTION of the step.
_TAIL_SHARE = 0.10
# A step is timed only where this share of it stands _NOISE_DEVIATIONS window-noise deviations
# clear: the tail from 10 % down to there is then the plant's, not the noise's.
_CLEAR_SHARE = 0.05
# A tail is read only where the hold runs this many of its time constants past its start: with
# fewer the final value is barely determined.
_TAIL_TIME_CONSTANTS = 2.0
# The time constants tried, as shares of the tail's length: for each, the final value and the
# tail's size are one linear least squares, so a grid finds the best with no starting guess.
_TAIL_GRID = np.geomspace(0.02, 2.0, 120)
# The averaging window of a timed approach (s): long against the cameras' noise, whose fused
# height still wanders 0.23 mm (RMS) over 1.8 s averages and 0.10 mm over 10 s.
TIMING_WINDOW_S = 5.0
# The fewest timed approaches a settling time is read from.
MIN_TIMED_HOLDS = 3


def settling_from_holds(u, y, window: int) -> int | None:
    """The longest time (samples) any large step of the record took to settle, or None.

    A hold whose step's ``_CLEAR_SHARE`` lies ``_NOISE_DEVIATIONS`` window-noise deviations
    clear of the mean of its last quarter is timed. From the last window average outside
    ``_TAIL_SHARE`` of the step (less half a window, the average's lag) to its end, its output is
    fitted as final value + size * exp(-k / tau), and it settled where that is within 2 % of
    the step (``_STEP_FRACTION``). A hold whose tail ran fewer than ``_TAIL_TIME_CONSTANTS`` time
    constants, or settled only past its end, was cut short: it only says the plant takes
    longer than the hold. So a record with such a hold longer than every timed one, or with
    fewer than ``MIN_TIMED_HOLDS`` timed, gives None.

    Args:
        u: (N, inputs) the currents; a hold is a run of unchanged currents (``hold_runs``).
        y: (N,) the output.
        window: the averaging window (samples).
    """
    u, y = np.asarray(u), np.asarray(y, dtype=float)
    starts, ends = hold_runs(u)
    average = window_averages(y, window)
    noise = window_noise(average, window)
    timed, cut_short = [], []
    for first, end in zip(starts, ends, strict=True):
        if end - first < 4 * window or first < window:
            continue
        before = y[first - window : first].mean()
        final = _final_value(y, first, end, window)
        if _CLEAR_SHARE * abs(final - before) < _NOISE_DEVIATIONS * noise:
            continue
        settled = _tail_settling(
            y[first:end], average[first + window - 1 : end], before, final, window
        )
        if settled is None:
            cut_short.append(end - first)
        else:
            timed.append(settled)
    if len(timed) < MIN_TIMED_HOLDS or (cut_short and max(cut_short) > max(timed)):
        return None
    return int(np.ceil(max(timed)))


def _tail_settling(held, averages, before: float, final: float, window: int) -> float | None:
    """Samples from a hold's start until its fitted tail is within 2 % of its step, or None.

    ``held``: the hold's output; ``averages``: its window averages from the first that reads
    only its own samples; ``before``: the output's mean over the window before it; ``final``:
    its final value (``_final_value``), which places the tail's start.
    """
    outside = np.flatnonzero(np.abs(averages - final) > _TAIL_SHARE * abs(final - before))
    start = int(round(outside[-1] + window - window / 2)) if outside.size else 0
    tail = held[start:]
    if tail.size < 2 * window:
        return None
    k = np.arange(tail.size, dtype=float)
    best = None
    for tau in _TAIL_GRID * tail.size:
        matrix = np.column_stack([np.ones(tail.size), np.exp(-k / tau)])
        (level, size), residual, *_ = np.linalg.lstsq(matrix, tail, rcond=None)
        sse = (
            float(residual[0])
            if residual.size
            else float(np.sum((matrix @ [level, size] - tail) ** 2))
        )
        if best is None or sse < best[0]:
            best = (sse, tau, level, size)
    _, tau, level, size = best
    step = abs(level - before)
    if tail.size < _TAIL_TIME_CONSTANTS * tau or step == 0.0:
        return None
    settled = start + tau * max(np.log(abs(size) / (_STEP_FRACTION * step)), 0.0)
    return settled if settled <= held.size else None


def _final_value(y, first: int, end: int, least: int) -> float:
    """A hold's final value: the mean of its last ``_FINAL_SHARE`` (at least ``least`` samples)."""
    return float(y[end - max(least, int((end - first) * _FINAL_SHARE)) : end].mean())
