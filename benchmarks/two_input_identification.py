"""Two-input identification (inlet and outlet together): accuracy and speed, one JSON line.

The planted system of tests/two_input_records.py (poles 0.9 and 0.7, a numerator per input with DC
gains 26.7 and -10, coloured noise), 2,000 samples, seeds 0-49, fitted at order 2 by PEM and
N4SID. Per method and drive: the largest and the 95th-percentile pole error and DC-gain relative
error, and the inputs' shared variance (``input_diagnostics.separation``). Drives:

- "independent": two independent white inputs;
- "split-range": one white command split between the inputs, the first taking its part above 0,
  the second its part below (each rectified, never both at once), as `maskless excite
  --valve-drive split-range` splits one command between the valves;
- "common": the second input minus the first plus 10 % independent noise (one drive moving both).

Timing: the best of ``--repeats`` order-2 PEM fits on 20,000 samples and order-4 N4SID fits on
100,000 samples of two independent inputs (benchmarks/identification.py times one input).
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from maskless.analysis.identification.input_diagnostics import separation
from maskless.analysis.identification.prediction_error import estimate_pem
from maskless.analysis.identification.subspace import estimate_n4sid

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from identification_records import largest_pole_error  # noqa: E402
from machine import machine_description  # noqa: E402
from two_input_records import POLES, simulate_two_inputs, true_dc_gains  # noqa: E402

ESTIMATORS = {
    "pem": lambda u, y: estimate_pem(u, y, 2, 1.0),
    "n4sid": lambda u, y: estimate_n4sid(u, y, 2, 1.0).model,
}


def drive(name: str, samples: int, seed: int) -> np.ndarray | None:
    """The (N, 2) inputs of one drive (None: the generator's independent white inputs)."""
    if name == "independent":
        return None
    rng = np.random.default_rng(10_000 + seed)
    command = rng.standard_normal(samples)
    if name == "split-range":
        return np.column_stack([np.maximum(command, 0.0), np.maximum(-command, 0.0)])
    return np.column_stack([command, -command + 0.1 * rng.standard_normal(samples)])


def spread(method: str, drive_name: str, samples: int, seeds: range) -> dict:
    """Pole and DC-gain errors of ``method`` over ``seeds``, and the drive's shared variance."""
    poles, gains, shared = [], [], []
    for seed in seeds:
        u, y = simulate_two_inputs(samples, seed, drive(drive_name, samples, seed))
        model = ESTIMATORS[method](u, y)
        poles.append(largest_pole_error(model.poles(), POLES))
        estimated = np.array([model.linear_model(input_index=i).dc_gain() for i in range(2)])
        gains.append(float(np.max(np.abs(estimated / true_dc_gains() - 1.0))))
        shared.append(max(separation(u, 4).shared_variance))
    return {
        "largest_pole_error": max(poles),
        "pole_error_p95": float(np.percentile(poles, 95)),
        "largest_dc_gain_relative_error": max(gains),
        "dc_gain_relative_error_p95": float(np.percentile(gains, 95)),
        "largest_shared_variance": max(shared),
    }


def best_time(estimate, samples: int, repeats: int) -> float:
    """The best of ``repeats`` fits of two independent inputs, seconds."""
    u, y = simulate_two_inputs(samples, seed=7)
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        estimate(u, y)
        best = min(best, time.perf_counter() - start)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3, help="fits per time; the best counts")
    parser.add_argument("--seeds", type=int, default=50, help="seeds per accuracy figure")
    args = parser.parse_args()
    if args.repeats < 1 or args.seeds < 1:
        raise ValueError(f"--repeats {args.repeats}, --seeds {args.seeds}: expected at least 1")
    seeds = range(args.seeds)
    figures = {
        "benchmark": "two_input_identification",
        "samples": 2000,
        "seeds": args.seeds,
        "accuracy": {
            f"{method}_{name}": spread(method, name, 2000, seeds)
            for method in ESTIMATORS
            for name in ("independent", "split-range", "common")
        },
        "pem_order2_20000_samples_seconds": best_time(ESTIMATORS["pem"], 20_000, args.repeats),
        "n4sid_order4_100000_samples_seconds": best_time(
            lambda u, y: estimate_n4sid(u, y, 4, 1.0), 100_000, args.repeats
        ),
        "machine": machine_description(),
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
