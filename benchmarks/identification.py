"""Identification speed and accuracy on simulated records, one JSON line.

- PEM, order 2, 20,000 samples (target < 2 s on a 2-core machine).
- N4SID, order 4, 100,000 samples (target <= 1.5 s), with the largest pole error (target 1e-2)
  and the validation simulation fit against the true model's own fit (target within 0.1 points).
- On the authors' record (when ../shared/paper-data is present): ARMAX orders 2 and 4 are stable,
  or their report says they are not.

Records: A(q) y = B(q) u + C(q) e with white u and coloured e (tests/identification_records.py);
a validation stretch follows the estimation one.
"""

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.innovations_model import InnovationsModel
from maskless.analysis.identification.prediction_error import estimate_pem
from maskless.analysis.identification.records import parse_range
from maskless.analysis.identification.report import Part, identify
from maskless.analysis.identification.subspace import estimate_n4sid

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from identification_records import (  # noqa: E402
    PAPER_DATA,
    TRUE_SYSTEMS,
    load_paper_record,
    simulate_record,
)
from machine import machine_description  # noqa: E402


def judge(estimate, order, samples, repeats):
    """Best time of ``repeats`` fits on ``samples``, and the model's accuracy on validation.

    The validation stretch holds 20 % more samples.
    """
    u, y, a, b = simulate_record(order, "coloured", int(samples * 1.2), seed=7)
    ue, ye, uv, yv = u[:samples], y[:samples], u[samples:], y[samples:]
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        model = estimate(ue, ye)
        best = min(best, time.perf_counter() - start)
    true = InnovationsModel(
        a=a[1:], b=b, k=np.zeros(order), sample_period_s=1.0, initial_state=np.zeros(order)
    )
    fits = {
        name: fit_percent(yv, m.simulate(uv, m.initial_state_for(uv, yv, "simulation")))
        for name, m in (("estimated", model), ("true", true))
    }
    poles = model.linear_model().poles()
    pole_error = max(min(abs(p - q) for q in poles) for p in TRUE_SYSTEMS[order]["poles"])
    return {
        "samples": samples,
        "seconds": best,
        "largest_pole_error": float(pole_error),
        "validation_fit_sim_percent": fits["estimated"],
        "true_model_validation_fit_sim_percent": fits["true"],
        "fit_gap_points": fits["true"] - fits["estimated"],
    }


def paper_armax_stability():
    record = load_paper_record()
    if record is None:
        return f"skipped: the authors' record is not at {PAPER_DATA}"
    u, y = record
    estimation = parse_range("0:0.6", y.size, "estimation")  # the authors' split
    validation = slice(estimation.stop, y.size)
    report, _ = identify(
        "armax",
        Part("estimation", u[estimation], y[estimation]),
        Part("validation", u[validation], y[validation]),
        [2, 4],
        0.048,
    )
    return [
        {"order": m["order"], "stable": m["stable"], "warned": "warning" in m}
        for m in report["models"]
    ]


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3, help="fits per figure; the best counts")
    args = parser.parse_args()
    if args.repeats < 1:
        raise ValueError(f"--repeats {args.repeats}: expected at least 1")
    figures = {
        "benchmark": "identification",
        "pem_order2": judge(lambda u, y: estimate_pem(u, y, 2, 1.0), 2, 20_000, args.repeats),
        "n4sid_order4": judge(
            lambda u, y: estimate_n4sid(u, y, 4, 1.0)[0], 4, 100_000, args.repeats
        ),
        "paper_record_armax": paper_armax_stability(),
        "targets": {
            "pem_order2_seconds": 2.0,
            "n4sid_order4_seconds": 1.5,
            "largest_pole_error": 1e-2,
            "fit_gap_points": 0.1,
        },
        "machine": machine_description(),
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
