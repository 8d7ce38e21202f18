"""N4SID's pole error with its data-chosen horizons against the former fixed horizon, one JSON line.

On the generated systems of tests/test_identification_suite.py (orders 1-6, poles up to 0.995,
equal-energy modes, output SNR 10) with two noise models, the suite's C(q) zeros and a slow one
whose predictor forgets slowly (zeros 0.95, 0.9, ...), at 2,000 and 10,000 samples, seeds 0-2.
Rules: "data" (the past horizon BIC picks, future 2n + 2: ``estimate_n4sid``'s default) and
"fixed" (past = future = max(2n + 2, 10), the rule before issue 14). Per condition: the median,
the largest and the mean of log10 of the matched pole error over the 18 fits, and the past
horizons chosen.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from maskless.analysis.identification.subspace import estimate_n4sid

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from machine import machine_description  # noqa: E402
from test_identification_suite import (  # noqa: E402
    NOISE_ZEROS,
    SYSTEMS,
    equal_energy_numerator,
    generated_record,
    matched_pole_error,
)

SLOW_NOISE_ZEROS = [0.95, 0.9, -0.5, 0.4, 0.3, -0.2]


def fixed_horizon(order: int) -> int:
    """The horizon before issue 14, for past and future alike."""
    return max(2 * order + 2, 10)


def compare(noise_zeros, samples: int, seeds) -> dict:
    errors = {"data": [], "fixed": []}
    chosen = []
    for order, poles in SYSTEMS.items():
        for seed in seeds:
            b = equal_energy_numerator(poles)
            u, y = generated_record(poles, b, noise_zeros[:order], samples, seed)
            fit = estimate_n4sid(u, y, order, 1.0)
            chosen.append(fit.past_horizon)
            errors["data"].append(matched_pole_error(fit.model.poles(), poles))
            h = fixed_horizon(order)
            fixed = estimate_n4sid(u, y, order, 1.0, past_horizon=h, future_horizon=h)
            errors["fixed"].append(matched_pole_error(fixed.model.poles(), poles))
    summary = {
        rule: {
            "median": float(np.median(values)),
            "largest": float(np.max(values)),
            "mean_log10": float(np.mean(np.log10(values))),
        }
        for rule, values in errors.items()
    }
    summary["past_horizons_chosen"] = [min(chosen), max(chosen)]
    return summary


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--seeds", type=int, default=3, help="seeds 0..SEEDS-1 per system")
    args = parser.parse_args()
    if args.seeds < 1:
        raise ValueError(f"--seeds {args.seeds}: expected at least 1")
    seeds = range(args.seeds)
    figures = {"benchmark": "subspace_horizon"}
    for noise, zeros in (("suite_noise", NOISE_ZEROS), ("slow_noise", SLOW_NOISE_ZEROS)):
        for samples in (2000, 10_000):
            figures[f"{noise}_{samples}"] = compare(zeros, samples, seeds)
    figures["machine"] = machine_description()
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
