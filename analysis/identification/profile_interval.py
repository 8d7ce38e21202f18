"""The 95 % profile interval of a parameter searched over a grid (a starting current).

A parameter profiled over a grid (at each value, the other parameters at their best) is told
apart from the best value when its lowest sum of squares rises by more than chi2(1, 0.95) = 3.84
residual variances: a likelihood-ratio interval for Gaussian errors. ``settled_curve`` and
``section_start`` profile starting currents so.
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
