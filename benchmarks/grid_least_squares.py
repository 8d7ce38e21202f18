"""The static curves' grid search: batched non-negative fits against one nnls call each; JSON.

One valve's coarse grid as ``settled_curve`` searches it in a Hammerstein fit (its own grid and
basis: starts 0 to 0.95 of the range, saturations past each up to 1.5; both signs), at --plays
play half-widths, on --levels settled levels with the other valve's two columns held. Times
``grid_least_squares.lowest_sums_of_squares`` over the whole grid against
``scipy.optimize.nnls`` called once per point and sign, on the same problems (the nnls loop on
the first --nnls-points points only, scaled to the grid), and checks the two agree there. The
figures are the median of --repeats runs; their ratio is what to compare across machines.
"""

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import scipy.optimize

from maskless.analysis.identification.grid_least_squares import lowest_sums_of_squares
from maskless.analysis.identification.hammerstein_problem import MAX_SATURATION, MAX_START
from maskless.analysis.identification.settled_curve import basis_grid, coarse_pairs, grid_starts

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402


def grid_problem(levels: int, seed: int):
    """(y (M,), held (M, 2), candidates (K, M, 2)): a valve's grid on planted noisy levels."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 1.0, levels)
    y = np.clip((x - 0.3) / 0.6, 0.0, 1.0) ** 2 + 0.01 * rng.standard_normal(levels)
    held = np.column_stack([rng.uniform(0.0, 1.0, levels), rng.uniform(0.0, 1.0, levels) ** 2])
    pairs = np.array(coarse_pairs(grid_starts(MAX_START), MAX_SATURATION))
    return y, held, basis_grid(x, pairs[:, 0], pairs[:, 1])


def nnls_loop(y, held, candidates) -> np.ndarray:
    """(K, 2) the same sums of squares by one scipy.optimize.nnls call per point and sign."""
    ones = np.ones((y.size, 1))
    out = np.empty((candidates.shape[0], 2))
    for k, own in enumerate(candidates):
        for column, sign in enumerate((1.0, -1.0)):
            matrix = np.hstack([ones, held, sign * own, -ones])
            out[k, column] = scipy.optimize.nnls(matrix, y)[1] ** 2
    return out


def seconds(run, repeats: int) -> float:
    runs = []
    for _ in range(repeats):
        start = time.perf_counter()
        run()
        runs.append(time.perf_counter() - start)
    return statistics.median(runs)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--levels", type=int, default=30, help="settled levels fitted")
    parser.add_argument("--plays", type=int, default=21, help="play half-widths searched")
    parser.add_argument("--nnls-points", type=int, default=500, help="grid points nnls times")
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure")
    args = parser.parse_args()
    if min(args.levels, args.plays, args.nnls_points, args.repeats) < 1:
        raise ValueError("--levels, --plays, --nnls-points and --repeats must be at least 1")
    y, held, candidates = grid_problem(args.levels, seed=0)
    points = candidates.shape[0]
    sample = candidates[: args.nnls_points]
    agreement = np.max(np.abs(lowest_sums_of_squares(y, held, sample) - nnls_loop(y, held, sample)))
    batched = seconds(lambda: lowest_sums_of_squares(y, held, candidates), args.repeats)
    looped = seconds(lambda: nnls_loop(y, held, sample), args.repeats) * points / sample.shape[0]
    print(
        json.dumps(
            {
                "benchmark": "grid_least_squares",
                "levels": args.levels,
                "grid_points_per_play": points,
                "plays": args.plays,
                "batched_seconds_per_valve": batched * args.plays,
                "nnls_seconds_per_valve": looped * args.plays,
                "speedup": looped / batched,
                "largest_difference_over_sum_of_squares": agreement / float(y @ y),
                "machine": machine_description(),
            }
        )
    )


if __name__ == "__main__":
    main()
