"""Population Monte Carlo speed, parallel efficiency, the Dask engine and memory; one JSON line.

Sections (``--only``):

- ``standard``: `maskless montecarlo --preset standard` (200 patients x 120 s, both controllers)
  on a local pool of ``--workers`` processes (default 2): the sweep's wall time, trials only, and
  the whole run with the summary and plot. Target: <= 60 s on 2 cores.
- ``efficiency``: the same first ``--trials`` trials in this process (1 worker) and on a 2-process
  pool: efficiency = t1 / (2 t2). The pool's time includes starting its processes, so the figure
  is a floor. Target: >= 80 %.
- ``dask``: those trials on a 2-worker Dask ``LocalCluster`` (started before the clock) and on a
  2-process pool; the ratio of their times, and whether the tables are the same bytes. Target:
  within 25 %.
- ``ablation``: the standard population for the offset-free LQG with one part removed at a time
  (patient motion; the paper's camera noise, leaving the modelled; the drawn bladder, valves and
  supply; and the drawn head too), each patient keeping the steps drawn for it: which part costs
  the 1 mm bar most; and the rank correlation of each draw with the p95 error.
- ``memory``: a 10,000-trial sweep of one controller over 6 simulated seconds each, on 2 processes,
  with the resident memory of the sweep and its workers sampled every second: the figure at 10 %,
  50 % and 90 % of the trials (the pool is gone by 100 %), and the largest. Target: flat (rows
  stream to disk).
"""

import argparse
import dataclasses
import json
import sys
import tempfile
import threading
import time
from pathlib import Path

import psutil

from maskless.analysis.population_summary import summarize_population
from maskless.diagrams.montecarlo import SweepRequest, TrialRunner, run_sweep
from maskless.diagrams.population import load_population, population_preset_path

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

SECTIONS = ("standard", "efficiency", "dask", "memory", "ablation")
# The standard population with one part removed at a time: (what is removed, the drawn plant
# constants set back to nominal in every patient, whose steps stay as drawn).
PLANT_DRAWS = (
    "stiffness_n_m",
    "leak_sonic_conductance_m3_s_pa",
    "inlet_sonic_conductance_m3_s_pa",
    "outlet_sonic_conductance_m3_s_pa",
    "supply_gauge_pressure_pa",
)
ABLATIONS = (
    ("nothing removed", ()),
    ("no patient motion", ()),
    ("modelled camera noise", ()),
    ("nominal bladder, valves and supply", PLANT_DRAWS),
    ("nominal head, bladder, valves and supply", ("head_mass_kg", *PLANT_DRAWS)),
)
MEMORY_TRIALS = 10_000


def sweep(config, out: Path, **options) -> dict:
    start = time.perf_counter()
    summary = run_sweep(SweepRequest(config=config, out=out, progress=False, **options))
    return {
        "trials_wall_s": summary["sweep"]["wall_time_s"],
        "whole_wall_s": time.perf_counter() - start,
        "summary": summary,
    }


def standard(folder: Path, workers: int) -> dict:
    config = load_population(population_preset_path("standard"))
    run = sweep(config, folder / "standard", workers=workers)
    return {
        "trials": config.trials,
        "controllers": config.controllers,
        "simulated_s_per_run": config.scenario.duration_s,
        "workers": workers,
        "trials_wall_s": run["trials_wall_s"],
        "whole_wall_s": run["whole_wall_s"],
        "target_wall_s": 60.0,
    }


def efficiency(folder: Path, trials: int) -> dict:
    config = dataclasses.replace(load_population(population_preset_path("standard")), trials=trials)
    one = sweep(config, folder / "one", workers=1)["trials_wall_s"]
    two = sweep(config, folder / "two", workers=2)["trials_wall_s"]
    same = (folder / "one" / "trials.csv").read_bytes() == (
        folder / "two" / "trials.csv"
    ).read_bytes()
    return {
        "trials": trials,
        "one_worker_s": one,
        "two_workers_s": two,
        "efficiency": one / (2 * two),
        "same_rows": same,
        "target_efficiency": 0.8,
    }


def dask(folder: Path, trials: int) -> dict:
    from distributed import LocalCluster

    config = dataclasses.replace(load_population(population_preset_path("standard")), trials=trials)
    pool = sweep(config, folder / "pool", workers=2)["trials_wall_s"]
    with LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster:
        cluster_s = sweep(config, folder / "dask", scheduler=cluster.scheduler_address)[
            "trials_wall_s"
        ]
    same = (folder / "pool" / "trials.csv").read_bytes() == (
        folder / "dask" / "trials.csv"
    ).read_bytes()
    return {
        "trials": trials,
        "pool_s": pool,
        "dask_local_cluster_s": cluster_s,
        "dask_over_pool": cluster_s / pool,
        "same_rows": same,
        "target_ratio": 1.25,
    }


class MemorySampler:
    """Resident memory of this process and its children, every ``period_s``."""

    def __init__(self, progress: Path, period_s: float = 1.0):
        self.samples: list[tuple[int, float]] = []  # (rows on disk, MiB)
        self._table, self._period_s = progress, period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self):
        me = psutil.Process()
        while not self._stop.wait(self._period_s):
            processes = [me, *me.children(recursive=True)]
            rss = 0
            for process in processes:
                try:
                    rss += process.memory_info().rss
                except psutil.NoSuchProcess:
                    pass
            rows = self._table.read_bytes().count(b"\n") - 1 if self._table.exists() else 0
            self.samples.append((rows, rss / 2**20))

    def __enter__(self):
        self._thread.start()
        return self

    def __exit__(self, *exc_info):
        self._stop.set()
        self._thread.join()


def memory(folder: Path) -> dict:
    config = load_population(population_preset_path("standard"))
    config = dataclasses.replace(
        config,
        trials=MEMORY_TRIALS,
        controllers=["offset-free-lqg"],
        positioning_time_s=1.0,
        step_time_s=2.0,
        worst_traces=1,
        scenario=dataclasses.replace(
            config.scenario,
            duration_s=6.0,
            metrics=dataclasses.replace(config.scenario.metrics, evaluation_delay_s=2.0),
        ),
    )
    out = folder / "memory"
    out.mkdir()
    with MemorySampler(out / "trials.csv") as sampler:
        run = sweep(config, out, workers=2)
    samples = sampler.samples

    def at(fraction):
        rows = fraction * MEMORY_TRIALS
        return next((mib for done, mib in samples if done >= rows), samples[-1][1])

    return {
        "trials": MEMORY_TRIALS,
        "simulated_s_per_run": config.scenario.duration_s,
        "trials_wall_s": run["trials_wall_s"],
        "rss_mib_at_10_percent": at(0.1),
        "rss_mib_at_50_percent": at(0.5),
        "rss_mib_at_90_percent": at(0.9),
        "rss_mib_max": max(mib for _, mib in samples),
        "samples": len(samples),
    }


class SameStepsRunner(TrialRunner):
    """The population's patients with some drawn constants set back to nominal.

    Each keeps the reference levels drawn for it (the same heights above the table), so a row
    differs from the standard population's only in what was removed.
    """

    def __init__(self, config, nominal_fields):
        super().__init__(config)
        p = config.scenario.pneumatic
        nominal = {
            "head_mass_kg": p.nominal_head_mass_kg,
            "stiffness_n_m": p.stiffness_n_m,
            "leak_sonic_conductance_m3_s_pa": p.leak_sonic_conductance_m3_s_pa,
            "inlet_sonic_conductance_m3_s_pa": p.inlet.sonic_conductance_m3_s_pa,
            "outlet_sonic_conductance_m3_s_pa": p.outlet.sonic_conductance_m3_s_pa,
            "supply_gauge_pressure_pa": p.supply_gauge_pressure_pa,
        }
        self._nominal = {name: nominal[name] for name in nominal_fields}

    def patient(self, trial, run=0):
        return dataclasses.replace(super().patient(trial, run), **self._nominal)


def ablated(removed: str):
    """The standard population, offset-free LQG only, with motion or the paper's noise removed."""
    config = load_population(population_preset_path("standard"))
    config.controllers = ["offset-free-lqg"]
    if removed == "no patient motion":
        config.scenario.patient_motion.enabled = False
    if removed == "modelled camera noise":
        for camera in config.scenario.cameras.values():
            camera.error.enabled = False
    return config


def ablation() -> dict:
    """Each ablation's figures (in this process: its runner is not the sweep's)."""
    figures = {}
    for removed, nominal_fields in ABLATIONS:
        config = ablated(removed)
        runner = SameStepsRunner(config, nominal_fields)
        rows = [row for trial in range(config.trials) for row in runner.rows(trial)]
        tolerance_m = config.scenario.metrics.tolerance_m
        found = summarize_population(rows, config.controllers, tolerance_m)["per_controller"]
        found = found["offset-free-lqg"]
        figures[removed] = {
            "p95_within_tolerance_fraction": found["p95_within_tolerance_fraction"],
            "p95_abs_error_mm": found["p95_abs_error_mm"],
            "time_within_tolerance_fraction": found["time_within_tolerance_fraction"],
            "unreachable_targets": found["unreachable_targets"],
            "holdable_steps_only": found["reachable_targets_only"],
        }
        if not nominal_fields and removed == "nothing removed":
            figures[removed]["spearman_with_p95_holdable"] = spearman_with_p95(rows)
    return figures


def spearman_with_p95(rows: list[dict]) -> dict:
    """Spearman's rank correlation of each draw with the p95 error, over the holdable steps."""
    from scipy import stats

    holdable = [row for row in rows if row["reachable"] and not row["error"]]
    p95 = [row["p95_abs_error_mm"] for row in holdable]
    draws = ["head_mass_kg", *PLANT_DRAWS, "positioned_lift_m"]
    found = {
        name: float(stats.spearmanr([row[name] for row in holdable], p95).statistic)
        for name in draws
    }
    found["abs_step_m"] = float(
        stats.spearmanr([abs(r["step_m"]) for r in holdable], p95).statistic
    )
    found["runs"] = len(holdable)
    return found


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--only", choices=SECTIONS, action="append", help="run only these")
    parser.add_argument("--workers", type=int, default=2, help="the standard sweep's processes")
    parser.add_argument(
        "--trials", type=int, default=40, help="trials of the efficiency and dask sections"
    )
    args = parser.parse_args()
    sections = args.only or SECTIONS
    figures = {"benchmark": "montecarlo"}
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        for section in sections:
            print(f"{section}...", file=sys.stderr, flush=True)
            if section == "standard":
                figures[section] = standard(folder, args.workers)
            elif section == "efficiency":
                figures[section] = efficiency(folder, args.trials)
            elif section == "dask":
                figures[section] = dask(folder, args.trials)
            elif section == "ablation":
                figures[section] = ablation()
            else:
                figures[section] = memory(folder)
    figures["machine"] = machine_description()
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
