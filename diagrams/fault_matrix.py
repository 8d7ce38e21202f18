"""The fault matrix: each fault example x seeds, judged by what the estimator and supervisor did.

``run_fault_matrix(FaultMatrixRequest(...))`` is ``maskless analyze faults``. A case is a shipped
fault example (``assets/faults/NAME.yaml``: its ``faults`` section, over the scenario) or
``nominal`` (no fault); each (case, seed) runs the whole closed loop once, on a spawned process
pool, and is a row of ``OUT/faults.csv``: when the fault was detected and by which check, how
soon the supervisor latched its safe state, how far the head went, the tracking p95, and how long
the beam was on while the true error exceeded the tolerance, or held while it did not (the truth
judges here; the loop never read it). A run that raised is a row naming the error, never a
crash of the matrix. ``OUT/faults.json`` holds each case's figures and the issue's targets met or
not (``analysis/fault_matrix_summary.py``); ``OUT/faults.png`` plots each figure per case.
"""

import dataclasses
import functools
import json
import math
import sys
import traceback
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from maskless.analysis.fault_matrix_summary import CaseFaults, summarize_fault_matrix
from maskless.analysis.trial_table import write_trial_table
from maskless.diagrams.background import usable_cores
from maskless.diagrams.output_folder import RunFolder
from maskless.diagrams.process_pool import pool_results
from maskless.diagrams.scenario import (
    Scenario,
    load_scenario,
    shipped_fault_examples,
    validate_scenario,
)
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from maskless.systems.units import m_to_mm

NOMINAL = "nominal"
FILES = ("faults.csv", "faults.json", "faults.png")
# The columns of a row, in order (``analysis/trial_table.py`` writes them).
COLUMNS = (
    "case",
    "seed",
    "error",
    "fault_start_s",
    "detected_by",
    "detection_latency_s",
    "safe_state_reason",
    "safe_state_latency_s",
    "state_at_end",
    "worst_excursion_mm",
    "p95_abs_error_mm",
    "beam_on_while_off_target_s",
    "beam_on_while_off_target_fraction",
    "beam_held_while_on_target_fraction",
    "beam_hold_fraction",
    "valve_currents_out_of_range",
    "max_gauge_pressure_kpa",
)


@dataclass(frozen=True)
class FaultMatrixRequest:
    """What ``maskless analyze faults`` was asked.

    Attributes:
        out: the folder of faults.csv, faults.json and faults.png.
        scenario: the scenario every case runs on (its own faults are replaced by the case's).
        cases: the fault examples' names (``faults/NAME.yaml``, or NAME), and ``nominal``;
            empty: every shipped example and ``nominal``.
        seeds: runs per case, seeds 0 .. seeds - 1.
        workers: processes (None: every core).
        overwrite: replace an earlier matrix in ``out``.
        progress: report each finished run (stderr).
    """

    out: Path
    scenario: Scenario
    cases: tuple[str, ...] = ()
    seeds: int = 20
    workers: int | None = None
    overwrite: bool = False
    progress: bool = True


def fault_cases(names: tuple[str, ...] = ()) -> dict[str, dict]:
    """Each case's faults by name (``nominal``: none), the shipped examples by default.

    Raises:
        ConfigError: a name that is no shipped example, listing those there are.
    """
    examples = {Path(name).stem: path for name, path in shipped_fault_examples().items()}
    names = names or (NOMINAL, *examples)
    cases = {}
    for name in names:
        stem = Path(name).stem if name != NOMINAL else name
        if stem == NOMINAL:
            cases[NOMINAL] = {}
        elif stem in examples:
            cases[stem] = load_scenario(examples[stem]).faults
        else:
            known = ", ".join([NOMINAL, *examples])
            raise ConfigError(f"--faults: no fault example {name!r}; expected one of {known}")
    return cases


def run_fault_matrix(request: FaultMatrixRequest) -> dict:
    """Runs every (case, seed), writes the files, returns the summary (with ``files``)."""
    if request.seeds < 1:
        raise ConfigError(f"--seeds {request.seeds}: expected at least 1")
    if not request.scenario.safety.enabled:
        raise ConfigError("safety.enabled = false: the fault matrix judges the safety supervisor")
    cases = fault_cases(request.cases)
    jobs = [(case, seed) for case in cases for seed in range(request.seeds)]
    # Each case's scenario is checked here, before anything runs: a fault that names a camera
    # the scenario lacks is refused in one line.
    for faults in cases.values():
        validate_scenario(dataclasses.replace(request.scenario, faults=faults))
    run = functools.partial(fault_matrix_row, request.scenario, cases)
    workers = max(1, min(request.workers or usable_cores(), len(jobs)))
    with RunFolder(request.out, FILES, overwrite=request.overwrite) as folder:
        results = (run(job) for job in jobs) if workers == 1 else pool_results(run, jobs, workers)
        rows = []
        for row in results:
            rows.append(row)
            if request.progress:
                print(
                    f"fault matrix: {len(rows)} / {len(jobs)} runs ({row['case']}, seed "
                    f"{row['seed']}{', ERROR ' + row['error'] if row['error'] else ''})",
                    file=sys.stderr,
                    flush=True,
                )
        order = {case: k for k, case in enumerate(cases)}
        rows.sort(key=lambda row: (order[row["case"]], row["seed"]))
        write_trial_table(folder.temporary("faults.csv"), COLUMNS, rows)
        summary = summarize_fault_matrix(
            rows,
            {
                case: CaseFaults(tuple((f.kind, f.target) for f in faults.values()))
                for case, faults in cases.items()
            },
            camera_count=len(request.scenario.cameras),
            pressure_limit_kpa=request.scenario.safety.max_gauge_pressure_pa / 1e3,
        )
        folder.temporary("faults.json").write_text(json.dumps(summary, indent=2) + "\n")
        from maskless.analysis.fault_matrix_plots import plot_fault_matrix

        plot_fault_matrix(folder.temporary("faults.png"), rows, list(cases), summary)
    summary["files"] = folder.final_paths(
        {"table": "faults.csv", "summary": "faults.json", "plot": "faults.png"}
    )
    return summary


def fault_matrix_row(scenario: Scenario, cases: dict[str, dict], job: tuple[str, int]) -> dict:
    """One run of the matrix as a row (``COLUMNS``); a run that raised is a row naming why."""
    case, seed = job
    faults = cases[case]
    row = dict.fromkeys(COLUMNS)
    start_s = min((f.start_s for f in faults.values()), default=None)
    row.update(case=case, seed=seed, error="", fault_start_s=start_s)
    try:
        run = simulate(dataclasses.replace(scenario, faults=faults, random_seed=seed))
        row.update(_judged(run, scenario, start_s))
    except Exception as error:  # a crash is a finding of the matrix, not the end of it
        last = traceback.extract_tb(error.__traceback__)[-1]
        row["error"] = f"{type(error).__name__}: {error} ({Path(last.filename).name}:{last.lineno})"
    return {k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}


def _judged(run, scenario: Scenario, start_s: float | None) -> dict:
    """A run's figures for its row: detection, safe state, excursion, p95, beam, valves."""
    metrics, s = run.metrics, run.signals
    safety = metrics["safety"]
    figures = {key: safety[key] for key in COLUMNS if key in safety}
    figures["p95_abs_error_mm"] = metrics["tracking"]["p95_abs_error_mm"]
    figures["max_gauge_pressure_kpa"] = safety.get("max_gauge_pressure_kpa")
    # The summary times each fault from its own start; the case's first answer counts, from the
    # case's first fault.
    faults = metrics["fault_detection"]["faults"].values()
    for what, latency_key, column, latency_column in (
        ("detected_by", "latency_s", "detected_by", "detection_latency_s"),
        ("safe_state_reason", "safe_state_latency_s", "safe_state_reason", "safe_state_latency_s"),
    ):
        answered = [f for f in faults if f[what] is not None]
        if answered:
            first = min(answered, key=lambda f, key=latency_key: f["start_s"] + f[key])
            figures[column] = first[what]
            figures[latency_column] = first["start_s"] + first[latency_key] - start_s
    times, head = s["head_height_m"].times_s, s["head_height_m"].values[0]
    if start_s is not None and start_s <= times[-1]:
        k = int(np.searchsorted(times, start_s))
        figures["worst_excursion_mm"] = m_to_mm(float(np.max(np.abs(head[k:] - head[k]))))
    p = scenario.pneumatic
    figures["valve_currents_out_of_range"] = sum(
        int(np.count_nonzero(~(np.isfinite(current) & (current >= 0) & (current <= full))))
        for current, full in (
            (s["safety.inlet_valve_current_a"].values[0], p.inlet.saturation_current_a),
            (s["safety.outlet_valve_current_a"].values[0], p.outlet.saturation_current_a),
        )
    )
    return figures


def format_fault_matrix(summary: dict) -> str:
    """The matrix as a table a person reads, then the targets."""
    header = (
        f"{'case':<22} {'runs':>4} {'err':>3} {'detected':>9} {'latency s':>10} "
        f"{'safe s':>7} {'excursion':>9} {'p95 mm':>7} {'beam on>tol %':>13} "
        f"{'held needl. %':>13}"
    )
    lines = [
        f"Fault matrix: {len(summary['cases'])} cases x {summary['seeds']} seeds "
        "(latency and p95: median/worst; beam: worst/median)",
        header,
    ]

    for case, f in summary["cases"].items():
        beam_on = f["beam_on_while_off_target_fraction"]
        held = f["beam_held_while_on_target_fraction"]
        excursion = "-" if f["worst_excursion_mm"] is None else f"{f['worst_excursion_mm']:.2f}"
        lines.append(
            f"{case:<22} {f['runs']:>4} {f['errors']:>3} {f['detected']:>4}/{f['runs']:<4} "
            f"{_two_of(f['detection_latency_s']):>10} {_two_of(f['safe_state_latency_s']):>7} "
            f"{excursion:>9} {_two_of(f['p95_abs_error_mm']):>7} "
            f"{_two_of(beam_on, ('worst', 'median'), 100, 3):>13} "
            f"{_two_of(held, ('worst', 'median'), 100, 1):>13}"
        )
    lines += ["", "Targets (issue 13):"]
    for t in summary["targets"]:
        worst = "-" if t["worst"] is None else f"{t['worst']:.4g}"
        lines.append(
            f"  {'met    ' if t['met'] else 'MISSED '} {t['target']}: worst {worst} "
            f"(bound {t['bound']:g})"
        )
    if "files" in summary:
        lines += ["Files:"] + [f"  {kind}: {path}" for kind, path in summary["files"].items()]
    return "\n".join(lines)


def _two_of(
    figure: dict, keys: tuple[str, str] = ("median", "worst"), scale: float = 1.0, digits: int = 2
) -> str:
    """Two of a case's figures ("median", "worst") as "A/B", scaled; "-" where there are none."""
    first, second = (figure[key] for key in keys)
    if first is None:
        return "-"
    return f"{scale * first:.{digits}f}/{scale * second:.{digits}f}"
