"""Clinical accuracy on one mannequin-like setting: the `accuracy` population, both controllers.

A preset of the population Monte Carlo (``maskless montecarlo --preset accuracy``): heads of 4-6 kg
on the nominal bladder, valves and supply, the cameras' modelled noise, no patient motion; each
trial brings the head to a drawn lift at 5 s and steps it by 2-10 mm up or down at 35 s, once with
the offset-free LQG and once with the paper's LQG. Every figure is judged over the same fixed
window in every trial, 20 s after the step to the end (55-120 s), settled or not (the definitions
of `maskless simulate`). The first ``--rendered-trials`` trials run again with rendered cameras
(offset-free LQG). Prints one JSON line; writes the sweep's table, summary and plot to ``--out``.

The standard population (``maskless montecarlo --preset standard``, benchmarks/montecarlo.py) is the
one to judge a controller on: patients, the paper's measured camera noise, patient motion.

Targets (issue 5): p95 <= 1 mm (aim 0.5 mm), settle <= 10 s (paper: ~24 s), overshoot <= 1 mm
(paper: 5 mm).
"""

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

from maskless.analysis.population_summary import summarize_population
from maskless.diagrams.montecarlo import SweepRequest, TrialRunner, run_sweep
from maskless.diagrams.population import load_population, population_preset_path
from maskless.diagrams.scenario import cameras_measured_by

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

RENDERED_CONTROLLER = "offset-free-lqg"


def rendered_rows(config, trials: int) -> tuple[list[dict], list[dict]]:
    """The first ``trials`` trials with rendered cameras, and the same trials modelled."""
    scenario = dataclasses.replace(
        config.scenario, cameras=cameras_measured_by(config.scenario.cameras, rendered=True)
    )
    one_controller = dataclasses.replace(config, controllers=[RENDERED_CONTROLLER])
    rendered = TrialRunner(dataclasses.replace(one_controller, scenario=scenario))
    modelled = TrialRunner(one_controller)
    return (
        [row for trial in range(trials) for row in rendered.rows(trial)],
        [row for trial in range(trials) for row in modelled.rows(trial)],
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--trials", type=int, default=None, help="patients (default: 24)")
    parser.add_argument("--out", type=Path, default=Path("accuracy"), help="the sweep's folder")
    parser.add_argument("--workers", type=int, default=None, help="processes (default: all)")
    parser.add_argument(
        "--rendered-trials",
        type=int,
        default=4,
        help="the first N trials also run with rendered cameras (offset-free LQG)",
    )
    args = parser.parse_args()
    config = load_population(population_preset_path("accuracy"))
    if args.trials is not None:
        config.trials = args.trials
    start = time.perf_counter()
    summary = run_sweep(
        SweepRequest(config=config, out=args.out, workers=args.workers, restart=True)
    )
    figures = {
        "benchmark": "accuracy",
        "population": str(population_preset_path("accuracy")),
        "trials": config.trials,
        "per_controller": summary["per_controller"],
        "sweep": summary["sweep"],
        "files": summary["files"],
    }
    if args.rendered_trials:
        rendered, modelled = rendered_rows(config, min(args.rendered_trials, config.trials))
        tolerance = config.scenario.metrics.tolerance_m
        figures["rendered_cameras"] = {
            "trials": len(rendered),
            "rendered": summarize_population(rendered, [RENDERED_CONTROLLER], tolerance)[
                "per_controller"
            ][RENDERED_CONTROLLER],
            "modelled, same trials": summarize_population(
                modelled, [RENDERED_CONTROLLER], tolerance
            )["per_controller"][RENDERED_CONTROLLER],
        }
    figures["wall_time_s"] = time.perf_counter() - start
    figures["targets"] = {"p95_abs_error_mm": 1.0, "settle_time_s": 10.0, "overshoot_mm": 1.0}
    figures["machine"] = machine_description()
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
