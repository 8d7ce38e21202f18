"""What a record tells of a starting current: its 95 % profile interval, and the levels about it.

A parameter profiled over a grid (at each value, the other parameters at their best) is told
apart from the best value when its lowest sum of squares rises by more than chi2(1, 0.95) = 3.84
residual variances: a likelihood-ratio interval for Gaussian errors. ``settled_curve`` and
``section_start`` profile starting currents so.

That interval trusts the curve's family. Between the settled level nearest below the best start
and the nearest above it, only the family's shape places the start: any start in that gap, with
a monotone curve flat below it, passes through the same levels. Where the family does not follow
the valve's curve, the profile is narrow and wrong. On patient 34 of the standard population,
still (``benchmarks/identified_control.py --scenario-presets``, stop 44 of issue 14), the
inlet's levels stop at 62.3 mA (at rest) and resume at 112.1 mA (9.5 mm); the quadratic put the
start at 82.7 mA with an interval of 78.4-85.5 mA, and at 78.3 mA (71.2-80.5) on the plant's
noise-free lift at the levels' spool positions (``tests/test_settled_curve.py``), where the
plant's start is 60 mA: the family, not the noise, misplaced it. So a start's interval always
covers that gap (``covering_levels_gap``), and the gap about every other start the profile
holds: the family placed those too. Covering the best start's gap alone, the outlet's section
of still patient 11 with its advised holds (stop 46 of issue 14) read 54.0 mA with an interval
of 46.4-57.1 mA, the plant's start 60 mA: its levels rested at 55.5 mA, flat, and next at
86.5 mA, and the profile's highest start, 57.1 mA, lies in that gap, which the plant's start
does too. Fitted to the plant's noise-free lift at those spools it reads 52.7 mA (46.0-58.0).
"""

import numpy as np

# The 95 % point of chi-squared with one degree of freedom: the profile's rise at the interval's
# ends.
CHI2_95 = 3.841


def profile_interval(grid, profile, threshold, best, step, lowest=0.0) -> tuple[float, float]:
    """(lowest, highest) value whose profile is within ``threshold``, not below ``lowest``.

    The profile is known at the grid's points only, so the best value's neighbours ``step``
    either side are in the interval too.

    Args:
        grid: (G,) the values searched.
        profile: (G,) the lowest sum of squares at each.
        threshold: the best sum of squares plus ``CHI2_95`` residual variances.
        best: the best value.
        step: the grid's step there.
        lowest: the lowest value the parameter can take.
    """
    kept = np.append(grid[profile <= threshold], best + np.array([-1.0, 1.0]) * step)
    return float(max(kept.min(), lowest)), float(kept.max())


def covering_levels_gap(interval, positions, start, lowest, highest) -> tuple[float, float]:
    """``interval`` widened to cover the gaps of settled levels about the starts it holds.

    Each start in ``interval`` (and ``start``) lies in a gap between settled levels, from the
    nearest level at or below it to the nearest above, and inside it only the family's shape
    placed it (module docstring); so the interval runs from the nearest level at or below its
    lowest start to the nearest above its highest, within the starts allowed: a level past
    them widens the interval to them, not beyond.

    Args:
        interval: (lowest, highest) the profile's interval.
        positions: where the valve's spool rested at each settled level the start was read from.
        start: the best start.
        lowest: the lowest start allowed: the gap's end where no level lies at or below it.
        highest: the highest start allowed: the gap's end where no level lies above it.
    """
    positions = np.asarray(positions, dtype=float)
    low_end, high_end = min(interval[0], start), max(interval[1], start)
    below, above = positions[positions <= low_end], positions[positions > high_end]
    gap_low = max(float(below.max()), lowest) if below.size else lowest
    gap_high = min(float(above.min()), highest) if above.size else highest
    return min(interval[0], gap_low), max(interval[1], gap_high)
