"""The population Monte Carlo: trials on a local process pool or a Dask cluster, rows on disk.

``run_sweep(SweepRequest(...))`` is ``maskless montecarlo``. Each trial draws a patient
(``population``) and runs it once per controller; each (trial, controller) is a row of
``OUT/trials.csv``: the draws, the seed and the tracking metrics, judged over the fixed window
from ``scenario.metrics.evaluation_delay_s`` after the judged step to the end (the definitions of
``maskless simulate``, ``analysis/metrics.py``). ``OUT/summary.json`` and ``OUT/population.png``
(CDFs, the worst trials' traces) follow from the table.

- **Engines.** A local process pool of every core by default. With a scheduler address, a Dask
  distributed cluster runs the same function: Dask rather than Ray because it is pure Python
  (two small wheels, no object store or raylet daemons), its ``LocalCluster`` starts in a second
  or two inside a test, and its workers can be started by hand on any machine that has maskless
  (``dask scheduler``, ``dask worker ADDRESS``).
- **One Diagram per controller per process.** A worker builds each controller's loop once, with
  the plant's constants and the reference's levels as Context parameters, and writes each trial's
  into a fresh Context (``simulate_loop``): nothing is rebuilt per trial.
- **The same rows anywhere.** Trial k draws from its own seed (``population.draw_patient``) and
  runs in a fresh Context, so a row does not depend on the worker, the order or the engine; the
  finished table is sorted by trial and controller, so the file itself is the same.
- **Streaming and resuming.** Rows are appended and flushed as trials finish, and at most a few
  trials per worker are in flight, so memory stays flat however many trials there are. Run again
  into the same folder, a sweep of the same configuration skips the trials already in its table
  (a larger ``--trials`` adds the rest); a different configuration is refused, not mixed in.
"""

import dataclasses
import functools
import hashlib
import json
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path

import numpy as np

from maskless.analysis.metrics import tracking_metrics
from maskless.analysis.trial_table import TrialTableWriter, read_trial_rows, write_trial_table
from maskless.diagrams.background import usable_cores
from maskless.diagrams.closed_loop import ClosedLoop, build_closed_loop
from maskless.diagrams.controller_design import NominalPneumatic
from maskless.diagrams.output_folder import FolderLock, output_folder
from maskless.diagrams.population import (
    MonteCarloConfig,
    Patient,
    draw_patient,
    patient_plant,
    patient_reach,
    sweep_scenario,
)
from maskless.diagrams.process_pool import IN_FLIGHT_PER_WORKER, bounded, pool_results
from maskless.diagrams.scenario import PaperLqg, controller_from_shorthand
from maskless.diagrams.simulation import simulate_loop
from maskless.errors import ConfigError, SweepError
from maskless.systems.control.safety_supervisor import safety_states
from maskless.systems.plant.pneumatic_plant import SWEPT_PARAMETERS
from maskless.systems.units import m_to_mm

PATIENT_COLUMNS = tuple(f.name for f in dataclasses.fields(Patient))
METRIC_COLUMNS = (
    "settled",
    "settle_time_s",
    "p95_abs_error_mm",
    "max_abs_error_mm",
    "rms_error_mm",
    "time_within_tolerance_fraction",
    "overshoot_mm",
    "final_error_mm",
    "safety_latched",
    "safety_held_air",
)
ROW_COLUMNS = (
    "trial",
    "run",
    "controller",
    *PATIENT_COLUMNS[2:],
    "reachable",
    *METRIC_COLUMNS,
    "error",
)
"""A row: the trial (the patient), its run (seed), the controller, the draws, whether the
controller's valves can hold the patient's head at both reference levels, the metrics (mm and s),
the reasons the safety supervisor had latched at the end (comma-separated) and whether it held the
air at any time, and, for a run that failed, why (empty otherwise)."""

TABLE_NAME, SUMMARY_NAME, PLOT_NAME = "trials.csv", "summary.json", "population.png"
RECORD_NAME, CONFIG_NAME = "sweep.json", "population.yaml"
# The signals a trial's metrics need; logging nothing else keeps each run cheap.
_LOGGED = ("head_height_m", "reference_head_height_m")
_SAFETY_LOGGED = ("safety.reasons", "safety.mode")


# Building a loop (Drake's scalar conversion of the templated plant for Linearize, the symbolic
# systems) is not safe in two threads at once: measured, two Dask threads building together made
# a plant without its attributes. Simulating built loops in parallel threads is.
_BUILDING = threading.Lock()


class TrialRunner:
    """Runs one sweep's trials: one built loop per controller, reused for every trial.

    Args:
        config: the sweep (validated, ``population.load_population``).
    """

    def __init__(self, config: MonteCarloConfig):
        """Prepares what every trial shares; the loops are built on first use."""
        self.config = config
        with _BUILDING:
            self.nominal = NominalPneumatic.of(config.scenario)
        self._loops: dict[str, ClosedLoop] = {}

    def loop(self, controller: str) -> ClosedLoop:
        """The built loop of ``controller`` (built once)."""
        if controller not in self._loops:
            with _BUILDING:
                self._loops[controller] = self._build(controller)
        return self._loops[controller]

    def _build(self, controller: str) -> ClosedLoop:
        scenario = sweep_scenario(self.config, levels_m=(0.0, 0.0))
        scenario.controller = controller_from_shorthand(controller)
        return build_closed_loop(
            scenario,
            record=_LOGGED + (_SAFETY_LOGGED if scenario.safety.enabled else ()),
            nominal=self.nominal,
            plant_context_parameters=SWEPT_PARAMETERS,
        )

    def patient(self, trial: int, run: int = 0) -> Patient:
        """Trial ``trial``'s draws, for its ``run``-th seed."""
        return draw_patient(self.config, trial, run)

    def simulate(self, patient: Patient, controller: str):
        """The run of ``patient`` with ``controller`` (a ``SimulationRun``)."""
        loop = self.loop(controller)
        return simulate_loop(
            loop,
            sweep_scenario(self.config, (0.0, 0.0), seed=patient.seed),
            plant_parameters=patient_plant(self.nominal.parameters, patient),
            reference_levels_m=patient.reference_levels_m(
                loop.start_height_m, self.nominal.parameters.rest_head_height_m
            ),
        )

    def rows(self, trial: int) -> list[dict]:
        """Trial ``trial``'s rows, per seed and controller; a failed run's row names why."""
        return [
            row
            for run in range(self.config.seeds_per_patient)
            for row in self.patient_rows(self.patient(trial, run))
        ]

    def patient_rows(self, patient: Patient) -> list[dict]:
        """``patient``'s rows, one per controller; a failed run's row names why."""
        drawn = dataclasses.asdict(patient)
        rows = []
        for controller in self.config.controllers:
            row = {
                **drawn,
                "controller": controller,
                "reachable": self._reachable(patient, controller),
                "error": None,
            }
            try:
                row.update(self._metrics(patient, controller))
            except Exception as error:  # noqa: BLE001 (a failed trial is a row, named loudly)
                row.update(dict.fromkeys(METRIC_COLUMNS))
                # One line: a row is one line of the table.
                row["error"] = " ".join(f"{type(error).__name__}: {error}".split())
            rows.append(row)
        return rows

    def _reachable(self, patient: Patient, controller: str) -> bool:
        """Whether the controller's valves can hold the patient's head at both levels."""
        outlet_used = not isinstance(controller_from_shorthand(controller), PaperLqg)
        lowest, highest = patient_reach(self.nominal.parameters, patient, outlet_used)
        start = patient.positioned_lift_m
        return all(lowest <= lift <= highest for lift in (start, start + patient.step_m))

    def _metrics(self, patient: Patient, controller: str) -> dict:
        run = self.simulate(patient, controller)
        head = run.signals["head_height_m"]
        metrics = tracking_metrics(
            head.times_s,
            head.values[0],
            run.signals["reference_head_height_m"].values[0],
            last_step_time_s=self.config.step_time_s,
            tolerance_m=self.config.scenario.metrics.tolerance_m,
            evaluation_delay_s=self.config.scenario.metrics.evaluation_delay_s,
        )
        if not np.all(np.isfinite(head.values)):
            raise FloatingPointError("the head height went non-finite")
        safety = {"safety_latched": None, "safety_held_air": None}
        if "safety.reasons" in run.signals:
            mode, reasons = run.signals["safety.mode"].values[0], run.signals["safety.reasons"]
            safety["safety_latched"] = safety_states(mode[-1:], reasons.values[:, -1:])[1][0]
            safety["safety_held_air"] = bool(np.any(mode > 0.5))
        return {
            "settled": metrics.settled,
            "settle_time_s": metrics.settle_time_s,
            "p95_abs_error_mm": _mm(metrics.p95_abs_error_m),
            "max_abs_error_mm": _mm(metrics.max_abs_error_m),
            "rms_error_mm": _mm(metrics.rms_error_m),
            "time_within_tolerance_fraction": metrics.time_within_tolerance_fraction,
            "overshoot_mm": _mm(metrics.overshoot_m),
            "final_error_mm": _mm(metrics.final_error_m),
            **safety,
        }

    def error_trace_mm(
        self, trial: int, run: int, controller: str
    ) -> tuple[np.ndarray, np.ndarray]:
        """(time from the judged step (s), head - reference (mm)) of one run, re-run."""
        run = self.simulate(self.patient(trial, run), controller)
        head = run.signals["head_height_m"]
        error = head.values[0] - run.signals["reference_head_height_m"].values[0]
        return head.times_s - self.config.step_time_s, m_to_mm(error)


def _mm(value_m: float | None) -> float | None:
    return None if value_m is None else float(m_to_mm(value_m))


def fingerprint(config: MonteCarloConfig) -> str:
    """What identifies a sweep's rows: its configuration, model files and the rows' format.

    The trial and seed counts are left out (a sweep may grow or shrink; every row stays on disk).
    A controller designed on a model file (``offset-free-lqg:MODEL.yaml``) is fingerprinted by
    the file's bytes: a model identified again is another controller. The package's version and
    the columns change the fingerprint too: rows from other code are not mixed in.
    """
    ignored = dataclasses.replace(config, trials=0, seeds_per_patient=0, worst_traces=0)
    digest = hashlib.sha256(repr(ignored).encode())
    digest.update(f"{metadata.version('maskless')} {ROW_COLUMNS}".encode())
    for controller in config.controllers:
        _, _, model_file = controller.partition(":")
        if model_file:
            digest.update(Path(model_file).read_bytes())
    return digest.hexdigest()


# The latest sweep's TrialRunner in this thread: a worker builds its loops for the first trial it
# gets, a long-lived Dask worker keeps no earlier sweep's loops, and two threads of one Dask worker
# never share a Context or a loop.
_RUNNERS = threading.local()


def trial_rows(config: MonteCarloConfig, key: str, trial: int) -> list[dict]:
    """Trial ``trial``'s rows, on whichever process runs it (``key``: ``fingerprint(config)``)."""
    return _runner(config, key).rows(trial)


def _runner(config: MonteCarloConfig, key: str) -> TrialRunner:
    """This thread's runner of the sweep ``key`` (``fingerprint(config)``), built on first use."""
    # The fingerprint leaves the seed count out, and the runner reads it.
    cache_key = (key, config.seeds_per_patient)
    if getattr(_RUNNERS, "key", None) != cache_key:
        _RUNNERS.key, _RUNNERS.runner = cache_key, TrialRunner(config)
    return _RUNNERS.runner


@dataclass(frozen=True)
class SweepRequest:
    """What ``maskless montecarlo`` runs.

    Attributes:
        config: the sweep (``population.load_population``); ``config.trials`` trials.
        out: the folder of the table, summary and plot.
        workers: local processes (None: one per core; 1 runs in this process).
        scheduler: a Dask scheduler's address (``tcp://host:8786``); the cluster's workers run
            the trials instead of a local pool.
        restart: discard the rows of an earlier sweep in ``out`` instead of resuming it.
        progress: show a progress bar on stderr.
    """

    config: MonteCarloConfig
    out: Path
    workers: int | None = None
    scheduler: str | None = None
    restart: bool = False
    progress: bool = True


def run_sweep(request: SweepRequest) -> dict:
    """Runs the trials not yet in ``request.out``'s table; writes the table, summary and plot.

    Returns:
        The summary (``summary.json``'s content): per controller, the figures over all trials.

    Raises:
        ConfigError: the folder holds a sweep of another configuration (and no ``restart``),
            another sweep is writing it (naming its pid), ``workers`` is not positive or given
            with a scheduler, or the scheduler cannot be reached.
        SweepError: a worker process died; the trials finished before are on disk.
    """
    if request.workers is not None and request.workers < 1:
        raise ConfigError(f"workers = {request.workers}: expected at least 1")
    if request.workers is not None and request.scheduler:
        raise ConfigError("workers: the cluster's workers run a sweep with a scheduler; not both")
    out = output_folder(request.out)
    # Two sweeps appending to one table would interleave their rows.
    with FolderLock(out):
        return _run_in(out, request)


def _run_in(out: Path, request: SweepRequest) -> dict:
    """``run_sweep`` in the folder ``out``, which it holds the lock of."""
    from maskless.analysis.population_summary import summarize_population

    config = request.config
    table = out / TABLE_NAME
    key = fingerprint(config)
    _claim_folder(out, config, key, request.restart)
    done = _finished_trials(table, config.controllers, config.seeds_per_patient)
    todo = [trial for trial in range(config.trials) if trial not in done]
    workers = request.workers or usable_cores()
    start = time.perf_counter()
    with TrialTableWriter(table, ROW_COLUMNS) as writer, _progress_bar(request, todo) as bar:
        try:
            for rows in _engine_results(request, key, todo, workers):
                for row in rows:
                    writer.append(row)
                bar.update(1)
        except (BrokenProcessPool, _killed_worker_error()) as error:
            raise SweepError(
                f"a worker process died ({type(error).__name__}); the trials finished are in "
                f"{table}: run the same sweep again to finish the rest (a script that starts a "
                'local pool needs the `if __name__ == "__main__":` guard)'
            ) from error
    wall_s = time.perf_counter() - start
    _, rows = read_trial_rows(table)
    # Every row stays on disk (a smaller --trials later loses none); the figures are this sweep's.
    rows = _sorted_rows(rows, config.controllers)
    write_trial_table(table, ROW_COLUMNS, rows)
    rows = [
        row
        for row in rows
        if row["trial"] < config.trials and row["run"] < config.seeds_per_patient
    ]
    summary = summarize_population(rows, config.controllers, config.scenario.metrics.tolerance_m)
    summary["sweep"] = {
        "trials": config.trials,
        "run_now": len(todo),
        "resumed": config.trials - len(todo),
        "engine": f"dask {request.scheduler}" if request.scheduler else "local process pool",
        "workers": None if request.scheduler else workers,
        "wall_time_s": wall_s,
        "simulated_s_per_trial": config.scenario.duration_s,
    }
    summary["files"] = {name: str(out / name) for name in (TABLE_NAME, SUMMARY_NAME, PLOT_NAME)}
    _plot(out / PLOT_NAME, config, key, rows)
    (out / SUMMARY_NAME).write_text(json.dumps(summary, indent=2) + "\n")
    return summary


def _claim_folder(out: Path, config: MonteCarloConfig, key: str, restart: bool) -> None:
    """Records the sweep in ``out``, or refuses a folder that holds another sweep's rows."""
    from pydrake.common.yaml import yaml_dump_typed

    record = out / RECORD_NAME
    table = out / TABLE_NAME
    if table.exists() and not record.exists() and not restart:
        raise ConfigError(
            f"{out}: holds {TABLE_NAME} but no {RECORD_NAME} saying which sweep made it; use "
            "another --out, or --restart to discard it"
        )
    if record.exists() and table.exists() and not restart:
        found = json.loads(record.read_text()).get("fingerprint")
        if found != key:
            raise ConfigError(
                f"{out}: holds the rows of a sweep of another configuration ({out / CONFIG_NAME});"
                " use another --out, or --restart to discard them"
            )
        return
    if restart:
        table.unlink(missing_ok=True)
    (out / CONFIG_NAME).write_text(yaml_dump_typed(dataclasses.replace(config, trials=0)))
    record.write_text(json.dumps({"fingerprint": key, "columns": list(ROW_COLUMNS)}) + "\n")


def _finished_trials(table: Path, controllers: list[str], seeds: int) -> set[int]:
    """The trials with a row per seed and controller in ``table``, none of them failed.

    A failed run is tried again: its cause (a killed worker, a full disk) may have passed.
    """
    if not table.exists():
        return set()
    _, rows = read_trial_rows(table)
    seen: dict[int, set[tuple[int, str]]] = {}
    for row in rows:
        if not row["error"]:
            seen.setdefault(row["trial"], set()).add((row["run"], row["controller"]))
    needed = {(run, controller) for run in range(seeds) for controller in controllers}
    return {trial for trial, found in seen.items() if found >= needed}


def _sorted_rows(rows: list[dict], controllers: list[str]) -> list[dict]:
    """One row per (trial, run, controller), sorted; the latest where a trial ran twice.

    A trial half-written by a killed sweep, or failed, and run again appears once.
    """
    order = {controller: index for index, controller in enumerate(controllers)}
    unique = {(row["trial"], row["run"], row["controller"]): row for row in rows}
    return [
        unique[key]
        for key in sorted(unique, key=lambda k: (k[0], k[1], order.get(k[2], len(order))))
    ]


def _engine_results(
    request: SweepRequest, key: str, trials: list[int], workers: int
) -> Iterator[list[dict]]:
    """Each trial's rows as it finishes, from the engine the request picks."""
    config = request.config
    if not trials:
        return iter(())
    if request.scheduler:
        return _dask_results(request.scheduler, config, key, trials)
    if workers == 1:
        return (trial_rows(config, key, trial) for trial in trials)
    return _pool_results(config, key, trials, workers)


def _pool_results(config, key: str, trials: list[int], workers: int) -> Iterator[list[dict]]:
    return pool_results(functools.partial(trial_rows, config, key), trials, workers)


def _dask_results(address: str, config, key: str, trials: list[int]) -> Iterator[list[dict]]:
    from distributed import Client, wait

    try:
        client = Client(address, timeout=30)
    except (OSError, ValueError, TimeoutError) as error:
        raise ConfigError(f"--scheduler {address}: cannot connect ({error})") from None
    with client:
        # Threads, not workers: `dask worker` runs one thread per core by default, each a trial.
        workers = max(1, sum(client.nthreads().values()))

        def first_done(pending):
            return wait(pending, return_when="FIRST_COMPLETED")

        yield from bounded(
            lambda trial: client.submit(
                trial_rows, config, key, trial, key=f"maskless-trial-{key[:12]}-{trial}"
            ),
            first_done,
            trials,
            workers * IN_FLIGHT_PER_WORKER,
        )


def _killed_worker_error() -> type:
    """Dask's error for a task whose workers kept dying (imported only when an error is caught)."""
    from distributed.scheduler import KilledWorker

    return KilledWorker


def _progress_bar(request: SweepRequest, todo: list[int]):
    from tqdm import tqdm

    done = request.config.trials - len(todo)
    return tqdm(
        total=request.config.trials,
        initial=done,
        unit="trial",
        file=sys.stderr,
        smoothing=0.1,
        disable=not request.progress,
    )


def _plot(path: Path, config: MonteCarloConfig, key: str, rows: list[dict]) -> None:
    """The CDFs and the worst trials' traces, re-run here (a few runs, deterministic).

    A sweep run in this process has its loops built already and reuses them.
    """
    from maskless.analysis.population_plots import plot_population, worst_trials

    runner = _runner(config, key)
    traces = {
        controller: [
            ((trial, run), *runner.error_trace_mm(trial, run, controller))
            for trial, run in worst_trials(rows, controller, config.worst_traces)
        ]
        for controller in config.controllers
    }
    plot_population(path, rows, config.controllers, traces, config.scenario.metrics.tolerance_m)
