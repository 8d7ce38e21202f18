"""The loop designed on a model identified per patient, against the nominal design; one JSON line.

For each of the first ``--trials`` patients of a population (default the standard preset: the
paper's camera noise, the patient's own motion, the drawn head, bladder, valves and supply), the
workflow's identification runs on that patient's plant as `maskless workflow --method M` runs it
on the nominal one: the method's experiment (``workflow.METHOD_EXCITATIONS``), then the model
(order 2). Then the patient's judged step (the population's own, the same seed as `maskless
montecarlo`) runs with the offset-free LQG designed on

- the nominal plant (what `maskless montecarlo` runs),
- the patient's PEM model,
- the patient's Hammerstein model (the valves opened through the inverse of its maps),
- the patient's true plant: an **oracle** (it reads the drawn parameters), for comparison only.

Each is judged as `maskless montecarlo` judges (``TrialRunner.patient_rows``): over the same
fixed window, 20 s after the step to the run's end. Prints the share of patients within ±1 mm
(p95), the p95's median, p90 and worst, per design; the identified starting currents against the
plant's; and the machine. ``--keep DIR`` keeps each patient's recordings and model files.

With ``--follow-advice``, a patient whose Hammerstein fit advised longer holds (it fell back to
its joint search, or its settled levels were few) runs the experiment `maskless workflow` then
prints (``workflow.advised_excitation``: those holds, twice the duration) and is identified
again: its starts, intervals and warnings under ``advised``. ``--only`` picks the patients by
number.
"""

import argparse
import dataclasses
import json
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import yaml

from maskless.analysis.identification.hammerstein import LEVELS_SCATTER_SHARE
from maskless.diagrams.excitation_run import excite_to_files
from maskless.diagrams.montecarlo import TrialRunner
from maskless.diagrams.population import (
    draw_patient,
    load_population,
    patient_plant,
    population_preset_path,
    sweep_scenario,
)
from maskless.diagrams.workflow import (
    METHOD_EXCITATIONS,
    WORKFLOW_METHODS,
    advised_excitation,
    identify_recording,
)
from maskless.systems.units import a_to_ma

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

ORACLE = "oracle: the patient's plant"
DESIGNS = ("nominal plant", "pem", "hammerstein", ORACLE)
ORDER = 2


def patient_result(
    population_file: str, trial: int, folder: str, identify_only: bool, follow_advice: bool
) -> dict:
    """One patient: both identifications on its plant, then its step under every design.

    With ``identify_only``, the Hammerstein identification alone; with ``follow_advice``, the
    advised experiment's too, where the fit advised one.
    """
    config = load_population(population_file)
    patient = draw_patient(config, trial)
    plant = patient_plant(config.scenario.pneumatic, patient)
    scenario = dataclasses.replace(
        sweep_scenario(config, (0.0, 0.0), seed=patient.seed), pneumatic=plant
    )
    out = Path(folder) / f"trial{trial}"
    identified, seconds = {}, {}
    for method in ("hammerstein",) if identify_only else WORKFLOW_METHODS:
        identified[method], seconds[method] = _identified(
            scenario, METHOD_EXCITATIONS[method], method, out / method
        )
    rows = {} if identify_only else _design_rows(config, patient, plant, identified)
    hammerstein = identified["hammerstein"]
    starts = _start_errors_ma(hammerstein, plant)
    advised = {}
    if follow_advice and hammerstein["advised_hold_s"] is not None:
        request = advised_excitation(
            METHOD_EXCITATIONS["hammerstein"], hammerstein["advised_hold_s"]
        )
        found, found_s = _identified(scenario, request, "hammerstein", out / "hammerstein-advised")
        advised = {
            "advised": {
                "hold_s": list(request.hold_s),
                "duration_s": request.duration_s,
                "starting_current_error_ma": _start_errors_ma(found, plant),
                "starting_currents": found["valves"],
                "warnings": found["warnings"],
                "identification_s": found_s,
            }
        }
    full_scale_mm = max(abs(valve["dc_gain_mm"]) for valve in hammerstein["valves"].values())
    scatter = hammerstein["levels_scatter"]
    return {
        "trial": trial,
        "reachable": rows["nominal plant"]["reachable"] if rows else None,
        "rows": rows,
        "starting_current_error_ma": starts,
        "starting_currents": hammerstein["valves"],
        "levels_scatter_share": None if scatter is None else 1e3 * scatter / full_scale_mm,
        "warnings": {method: found["warnings"] for method, found in identified.items()},
        "identification_s": seconds,
        **advised,
    }


def _identified(scenario, request, method: str, folder: Path) -> tuple[dict, float]:
    """``method``'s identification of ``request`` run on ``scenario``, and its wall time (s).

    The experiment goes to ``folder``/excitation, the model to ``folder``/identification.
    """
    began = time.perf_counter()
    excited = excite_to_files(scenario, request, folder / "excitation")
    found = identify_recording(method, excited, ORDER, folder / "identification")
    return found, time.perf_counter() - began


def _start_errors_ma(identified: dict, plant) -> dict:
    """Each valve's identified starting current less the plant's (mA)."""
    return {
        name: identified["valves"][name]["starting_current_ma"] - a_to_ma(valve.starting_current_a)
        for name, valve in (("inlet", plant.inlet), ("outlet", plant.outlet))
    }


def _design_rows(config, patient, plant, identified: dict) -> dict:
    """The patient's row per design (``TrialRunner.patient_rows``)."""
    # The oracle's loop is designed on the patient's plant; the others on the nominal one, their
    # controllers on the identified files. Every loop runs the patient's plant.
    oracle_config = dataclasses.replace(
        config, scenario=dataclasses.replace(config.scenario, pneumatic=plant)
    )
    designs = {
        "nominal plant": (config, "offset-free-lqg"),
        "pem": (config, f"offset-free-lqg:{identified['pem']['model_file']}"),
        "hammerstein": (config, f"offset-free-lqg:{identified['hammerstein']['model_file']}"),
        ORACLE: (oracle_config, "offset-free-lqg"),
    }
    rows = {}
    for design, (design_config, controller) in designs.items():
        runner = TrialRunner(dataclasses.replace(design_config, controllers=[controller]))
        (rows[design],) = runner.patient_rows(patient)
    return rows


def summarize(results: list[dict]) -> dict:
    """Per design: share within ±1 mm (p95), the p95's quantiles; all runs and holdable ones."""
    summary = {}
    for design in DESIGNS if results[0]["rows"] else ():
        per_design = {}
        for label, kept in (
            ("all", results),
            ("holdable", [r for r in results if r["reachable"]]),
        ):
            p95 = np.array(
                [
                    np.inf if r["rows"][design]["error"] else r["rows"][design]["p95_abs_error_mm"]
                    for r in kept
                ]
            )
            finite = p95[np.isfinite(p95)]
            per_design[label] = {
                "patients": len(kept),
                "failed_runs": int(np.sum(~np.isfinite(p95))),
                "p95_within_1mm_share": float(np.mean(p95 <= 1.0)) if kept else None,
                "p95_mm_median_p90_worst": (
                    [float(np.median(finite)), float(np.quantile(finite, 0.9)), float(finite.max())]
                    if finite.size
                    else None
                ),
            }
        summary[design] = per_design
    summary["hammerstein_starting_currents"] = _starts_summary(results)
    followed = [r["advised"] for r in results if "advised" in r]
    if followed:
        summary["advised"] = {
            "patients": len(followed),
            "starting_currents": _starts_summary(followed),
            "warned": int(sum(bool(r["warnings"]) for r in followed)),
        }
    summary["identifications_warned"] = {
        method: int(sum(bool(r["warnings"][method]) for r in results))
        for method in results[0]["warnings"]
    }
    shares = [r["levels_scatter_share"] for r in results if r["levels_scatter_share"] is not None]
    summary["hammerstein_levels_scatter_share"] = {
        "records": len(shares),
        "min_median_max": [float(np.min(shares)), float(np.median(shares)), float(np.max(shares))]
        if shares
        else None,
        "above_warning_share": int(
            sum((r["levels_scatter_share"] or 0.0) > LEVELS_SCATTER_SHARE for r in results)
        ),
    }
    return summary


def _starts_summary(results: list[dict]) -> dict:
    """Per valve: starts within 5 mA of the plant's, the mean and the worst error (mA)."""
    errors = {
        name: np.array([r["starting_current_error_ma"][name] for r in results])
        for name in ("inlet", "outlet")
    }
    return {
        name: {
            "within_5ma": int(np.sum(np.abs(e) <= 5.0)),
            "mean_ma": float(e.mean()),
            "worst_ma": float(e[np.argmax(np.abs(e))]),
        }
        for name, e in errors.items()
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    source = parser.add_mutually_exclusive_group()
    source.add_argument("--preset", default="standard", help="a shipped population (standard)")
    source.add_argument("--population", type=Path, help="a population file of your own")
    parser.add_argument(
        "--scenario-presets",
        nargs="*",
        metavar="NAME",
        help="the scenario presets instead of the population's (none: a still head, the "
        "cameras' modelled noise)",
    )
    parser.add_argument("--trials", type=int, default=40, help="the first N patients (40)")
    parser.add_argument(
        "--only", type=int, nargs="+", metavar="N", help="these patients instead of the first N"
    )
    parser.add_argument(
        "--follow-advice",
        action="store_true",
        help="with --identify-only: run the experiment a fit's advice asks for, and fit it too",
    )
    parser.add_argument("--jobs", type=int, default=2, help="processes (2)")
    parser.add_argument("--keep", type=Path, default=None, metavar="DIR", help="keep the files")
    parser.add_argument(
        "--identify-only",
        action="store_true",
        help="the Hammerstein identification alone: its starts and scatter, no loops",
    )
    args = parser.parse_args()
    if args.trials < 1 or args.jobs < 1:
        raise ValueError(f"--trials {args.trials}, --jobs {args.jobs}: expected at least 1 each")
    if args.follow_advice and not args.identify_only:
        raise ValueError("--follow-advice: expected with --identify-only")
    if args.only is not None and min(args.only) < 0:
        raise ValueError(f"--only {args.only}: expected patient numbers from 0")
    trials = args.only or list(range(args.trials))
    population_file = str(args.population or population_preset_path(args.preset))
    began = time.perf_counter()
    with tempfile.TemporaryDirectory() as scratch:
        if args.scenario_presets is not None:
            population = yaml.safe_load(Path(population_file).read_text())
            population["scenario_presets"] = args.scenario_presets
            population_file = str(Path(scratch) / "population.yaml")
            Path(population_file).write_text(yaml.safe_dump(population))
        folder = str(args.keep or scratch)
        with ProcessPoolExecutor(args.jobs) as pool:
            futures = [
                pool.submit(
                    patient_result,
                    population_file,
                    trial,
                    folder,
                    args.identify_only,
                    args.follow_advice,
                )
                for trial in trials
            ]
            results = []
            for future in futures:
                results.append(future.result())
                print(f"patient {len(results)} of {len(trials)}", file=sys.stderr, flush=True)
    print(
        json.dumps(
            {
                "benchmark": "identified_control",
                "population": str(args.population or args.preset),
                "scenario_presets": args.scenario_presets,
                "trials": trials,
                "wall_s": time.perf_counter() - began,
                "summary": summarize(results),
                "patients": results,
                "machine": machine_description(),
            }
        )
    )


if __name__ == "__main__":
    main()
