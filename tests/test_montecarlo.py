"""The population Monte Carlo: rows as `simulate` judges them, the same on every engine.

Also: resumed after a kill, refused when mixed with another sweep, and failures named.
"""

import dataclasses
import json
import os
import signal
import subprocess
import sys
import time

import pytest

from maskless.analysis.trial_table import read_trial_rows
from maskless.diagrams.cli import main
from maskless.diagrams.closed_loop import (
    PNEUMATIC_PLANT_NAME,
    REFERENCE_NAME,
    set_plant_parameters,
)
from maskless.diagrams.montecarlo import (
    ROW_COLUMNS,
    SweepRequest,
    TrialRunner,
    fingerprint,
    run_sweep,
)
from maskless.diagrams.output_folder import LOCK_NAME, FolderLock
from maskless.diagrams.population import UniformRange, patient_plant, sweep_scenario
from maskless.diagrams.scenario import controller_from_shorthand
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from tests.tiny_population import tiny_population, tiny_population_file


def sweep(config, out, **options):
    return run_sweep(SweepRequest(config=config, out=out, progress=False, **options))


def command_args(population, out, trials=1, workers=1) -> list[str]:
    """`maskless montecarlo`'s arguments for a small sweep, no progress bar."""
    return [
        "montecarlo",
        "--population",
        str(population),
        "--trials",
        str(trials),
        *(["--workers", str(workers)] if workers else []),
        "--out",
        str(out),
        "--no-progress",
    ]


def table_bytes(out):
    return (out / "trials.csv").read_bytes()


def test_a_nominal_patients_row_is_what_simulate_reports_for_the_same_run(tmp_path):
    """One built loop with the trial written into its Context == a loop built for the trial."""
    config = tiny_population(tmp_path, trials=2)
    nominal = config.scenario.pneumatic
    config.population.head_mass_kg = UniformRange(nominal.head_mass_kg, nominal.head_mass_kg)
    for name in ("stiffness", "leak", "inlet_conductance", "outlet_conductance"):
        setattr(config.population, f"{name}_factor", UniformRange(1.0, 1.0))
    supply = nominal.supply_gauge_pressure_pa
    config.population.supply_gauge_pressure_pa = UniformRange(supply, supply)
    runner = TrialRunner(config)
    rows = runner.rows(1)
    patient = runner.patient(1)
    start_m = runner.loop("offset-free-lqg").start_height_m
    levels = patient.reference_levels_m(start_m, nominal.rest_head_height_m)
    for row in rows:
        offsets = [level - start_m for level in levels[1:]]
        scenario = sweep_scenario(config, offsets, seed=patient.seed)
        scenario.controller = controller_from_shorthand(row["controller"])
        metrics = simulate(scenario).metrics
        tracking = metrics["tracking"]
        for name in ("p95_abs_error_mm", "max_abs_error_mm", "overshoot_mm", "final_error_mm"):
            assert row[name] == pytest.approx(tracking[name], abs=1e-9), name
        assert row["time_within_tolerance_fraction"] == tracking["time_within_tolerance_fraction"]
        assert row["safety_latched"] == ",".join(metrics["safety"]["latched_at_end"])
        held = any(e["action"] != "continue" for e in metrics["safety"]["events"])
        assert row["safety_held_air"] == held


def test_the_draw_reaches_the_plant_and_the_reference_and_nothing_else(tmp_path):
    """The controller is designed on the nominal plant and starts the same for every patient."""
    config = tiny_population(tmp_path)
    runner = TrialRunner(config)
    p = config.scenario.pneumatic
    assert runner.nominal.parameters == dataclasses.replace(p, head_mass_kg=p.nominal_head_mass_kg)
    for controller in config.controllers:
        diagram = runner.loop(controller).diagram
        readers = {
            # A system's "NAME.inputs" Multiplexer is its input port.
            source.get_name(): sorted(
                {system.get_name().removesuffix(".inputs") for system, _ in inputs}
            )
            for source, inputs in _readers(diagram).items()
        }
        assert readers[f"{PNEUMATIC_PLANT_NAME}.parameters"] == [PNEUMATIC_PLANT_NAME]
        assert readers[f"{REFERENCE_NAME}.parameters"] == [REFERENCE_NAME]
        contexts = []
        for trial in (0, 1):
            patient = runner.patient(trial)
            context = diagram.CreateDefaultContext()
            set_plant_parameters(diagram, context, patient_plant(p, patient))
            contexts.append(context)
        for system in diagram.GetSystems():
            if system.get_name() in (PNEUMATIC_PLANT_NAME, f"{PNEUMATIC_PLANT_NAME}.parameters"):
                continue
            first, second = (diagram.GetSubsystemContext(system, c) for c in contexts)
            assert _state_and_parameters(first) == _state_and_parameters(second), system.get_name()
        assert _state_and_parameters(
            diagram.GetSubsystemContext(
                diagram.GetSubsystemByName(PNEUMATIC_PLANT_NAME), contexts[0]
            )
        ) != _state_and_parameters(
            diagram.GetSubsystemContext(
                diagram.GetSubsystemByName(PNEUMATIC_PLANT_NAME), contexts[1]
            )
        )


def _readers(diagram):
    """Source system -> the (system, input index) its outputs feed."""
    readers = {}
    for (system, input_index), (source, _) in diagram.connection_map().items():
        readers.setdefault(source, []).append((system, input_index))
    return readers


def _state_and_parameters(context):
    state = (
        context.get_discrete_state_vector().CopyToVector().tolist()
        if (context.num_discrete_state_groups())
        else []
    )
    continuous = context.get_continuous_state_vector().CopyToVector().tolist()
    numeric = [
        context.get_numeric_parameter(i).CopyToVector().tolist()
        for i in range(context.num_numeric_parameter_groups())
    ]
    return state, continuous, numeric


def test_one_row_per_trial_and_controller_with_the_draws_and_metrics(tmp_path):
    config = tiny_population(tmp_path, trials=3)
    summary = sweep(config, tmp_path / "mc", workers=1)
    columns, rows = read_trial_rows(tmp_path / "mc" / "trials.csv")
    assert columns == list(ROW_COLUMNS)
    assert [(r["trial"], r["controller"]) for r in rows] == [
        (t, c) for t in range(3) for c in config.controllers
    ]
    assert all(r["error"] is None and r["p95_abs_error_mm"] >= 0 for r in rows)
    assert summary["per_controller"]["offset-free-lqg"]["runs"] == 3
    assert json.loads((tmp_path / "mc" / "summary.json").read_text()) == summary
    assert (tmp_path / "mc" / "population.png").read_bytes()[:4] == b"\x89PNG"


def local_cluster(distributed, tmp_path, workers: int, threads: int):
    """A Dask cluster of worker processes, with its scratch folder in the test's, not /tmp."""
    return distributed.LocalCluster(
        n_workers=workers,
        threads_per_worker=threads,
        processes=True,
        dashboard_address=None,
        local_directory=str(tmp_path),
    )


def test_the_same_rows_in_process_on_a_local_pool_and_on_a_dask_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    config = tiny_population(tmp_path)
    sweep(config, tmp_path / "one", workers=1)
    sweep(config, tmp_path / "pool", workers=2)
    with local_cluster(distributed, tmp_path, workers=2, threads=1) as cluster:
        summary = sweep(config, tmp_path / "dask", scheduler=cluster.scheduler_address)
    assert summary["sweep"]["engine"].startswith("dask tcp://")
    assert table_bytes(tmp_path / "pool") == table_bytes(tmp_path / "one")
    assert table_bytes(tmp_path / "dask") == table_bytes(tmp_path / "one")


def test_a_larger_sweep_into_the_same_folder_runs_only_the_new_trials(tmp_path):
    config = tiny_population(tmp_path)
    sweep(dataclasses.replace(config, trials=3), tmp_path / "grown", workers=1)
    summary = sweep(config, tmp_path / "grown", workers=1)
    assert (summary["sweep"]["run_now"], summary["sweep"]["resumed"]) == (3, 3)
    sweep(config, tmp_path / "fresh", workers=1)
    assert table_bytes(tmp_path / "grown") == table_bytes(tmp_path / "fresh")


def test_a_sweep_killed_half_way_finishes_the_rest_only(tmp_path):
    """SIGKILL the command while its pool works; its workers go too, and a re-run completes."""
    population = tiny_population_file(tmp_path)
    config = tiny_population(tmp_path, trials=40)
    out = tmp_path / "killed"
    command = [
        sys.executable,
        "-m",
        "maskless.diagrams.cli",
        *command_args(population, out, trials=40, workers=2),
    ]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    table = out / "trials.csv"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline:
        if table.exists() and len(table.read_bytes().splitlines()) > 8:
            break
        time.sleep(0.05)
    children = _children(process.pid)
    process.send_signal(signal.SIGKILL)
    process.wait()
    _, rows = read_trial_rows(table)
    finished = len({r["trial"] for r in rows})
    assert 4 <= finished < 40
    _wait_gone(children)
    summary = sweep(config, out, workers=2)
    assert summary["sweep"]["resumed"] >= finished - 1  # a trial may have only one row on disk
    assert summary["sweep"]["run_now"] <= 40 - finished + 1
    sweep(config, tmp_path / "whole", workers=2)
    assert table_bytes(out) == table_bytes(tmp_path / "whole")


def _children(pid: int) -> list[int]:
    psutil = pytest.importorskip("psutil")
    return [child.pid for child in psutil.Process(pid).children(recursive=True)]


def _wait_gone(pids: list[int], timeout_s: float = 10.0) -> None:
    """The pool's workers end on their own once their parent is killed."""
    deadline = time.monotonic() + timeout_s
    alive = pids
    while alive and time.monotonic() < deadline:
        alive = [pid for pid in alive if _running(pid)]
        time.sleep(0.1)
    assert not alive, f"workers {alive} outlived the killed sweep"


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        with open(f"/proc/{pid}/stat") as stat:  # a zombie has exited
            return stat.read().split(") ")[1][0] != "Z"
    except FileNotFoundError:  # reaped between the two looks
        return False


def test_a_folder_of_another_sweep_is_refused_unless_restarted(tmp_path):
    config = tiny_population(tmp_path, trials=1)
    sweep(config, tmp_path / "mc", workers=1)
    other = dataclasses.replace(config, seed=config.seed + 1)
    assert fingerprint(other) != fingerprint(config)
    with pytest.raises(ConfigError, match="holds the rows of a sweep of another configuration"):
        sweep(other, tmp_path / "mc", workers=1)
    summary = sweep(other, tmp_path / "mc", workers=1, restart=True)
    assert summary["sweep"]["run_now"] == 1
    grown = dataclasses.replace(config, trials=9, seeds_per_patient=3, worst_traces=0)
    assert fingerprint(grown) == fingerprint(config)


def test_a_folder_another_sweep_is_writing_is_refused_and_free_again_after_it(tmp_path):
    config = tiny_population(tmp_path, trials=1)
    out = tmp_path / "mc"
    out.mkdir()
    with FolderLock(out):  # another sweep, as far as the lock can tell (its own open file)
        with pytest.raises(ConfigError, match=rf"in use by another run \(pid {os.getpid()}\)"):
            sweep(config, out, workers=1)
        assert not (out / "trials.csv").exists()
    assert sweep(config, out, workers=1)["sweep"]["run_now"] == 1
    assert not (out / LOCK_NAME).exists()


def test_a_failed_run_is_a_row_that_says_why_and_fails_the_command(tmp_path, monkeypatch, capsys):
    original = TrialRunner.simulate

    def broken(self, patient, controller):
        if patient.trial == 1 and controller == "paper-lqg":
            raise RuntimeError("solver diverged")
        return original(self, patient, controller)

    monkeypatch.setattr(TrialRunner, "simulate", broken)
    population = tiny_population_file(tmp_path)
    code = main(command_args(population, tmp_path / "mc", trials=2))
    assert code == 1
    assert "1 runs failed" in capsys.readouterr().err
    _, rows = read_trial_rows(tmp_path / "mc" / "trials.csv")
    failed = [r for r in rows if r["error"]]
    assert [(r["trial"], r["controller"], r["error"]) for r in failed] == [
        (1, "paper-lqg", "RuntimeError: solver diverged")
    ]
    assert failed[0]["p95_abs_error_mm"] is None
    summary = json.loads((tmp_path / "mc" / "summary.json").read_text())
    assert summary["per_controller"]["paper-lqg"]["failed"] == 1


def test_the_command_prints_the_summary_and_bad_flags_are_named(tmp_path, capsys):
    population = tiny_population_file(tmp_path)
    out = tmp_path / "mc"
    assert main([*command_args(population, out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["sweep"]["trials"] == 1
    with pytest.raises(SystemExit):
        main(["montecarlo", "--trials", "0"])
    assert "expected at least 1" in capsys.readouterr().err
    assert main(["montecarlo", "--preset", "nope", "--out", str(out)]) == 2
    assert "no population preset 'nope'" in capsys.readouterr().err


def test_a_smaller_sweep_keeps_every_row_on_disk_and_judges_its_own(tmp_path):
    config = tiny_population(tmp_path, trials=3)
    sweep(config, tmp_path / "mc", workers=1)
    whole = table_bytes(tmp_path / "mc")
    summary = sweep(dataclasses.replace(config, trials=1), tmp_path / "mc", workers=1)
    assert summary["per_controller"]["paper-lqg"]["runs"] == 1
    assert table_bytes(tmp_path / "mc") == whole
    assert sweep(config, tmp_path / "mc", workers=1)["sweep"]["run_now"] == 0


def test_a_failed_run_is_tried_again_when_the_sweep_resumes(tmp_path, monkeypatch):
    config = tiny_population(tmp_path, trials=2)
    original = TrialRunner.simulate

    def broken(self, patient, controller):
        if patient.trial == 1:
            raise RuntimeError("a line\nand another")
        return original(self, patient, controller)

    monkeypatch.setattr(TrialRunner, "simulate", broken)
    sweep(config, tmp_path / "mc", workers=1)
    _, rows = read_trial_rows(tmp_path / "mc" / "trials.csv")
    assert [r["error"] for r in rows if r["trial"] == 1] == ["RuntimeError: a line and another"] * 2
    monkeypatch.setattr(TrialRunner, "simulate", original)
    summary = sweep(config, tmp_path / "mc", workers=1)
    assert (summary["sweep"]["run_now"], summary["sweep"]["resumed"]) == (1, 1)
    sweep(config, tmp_path / "fresh", workers=1)
    assert table_bytes(tmp_path / "mc") == table_bytes(tmp_path / "fresh")


def test_a_model_file_controller_is_found_beside_the_population_and_fingerprinted(tmp_path):
    from maskless.diagrams.population import load_population
    from maskless.errors import MissingFileError
    from tests.tiny_population import TINY_POPULATION

    text = TINY_POPULATION.replace("paper-lqg]", "offset-free-lqg:model.yaml]")
    path = tiny_population_file(tmp_path, text)
    with pytest.raises(MissingFileError, match="model.yaml: model file not found"):
        load_population(path)
    (tmp_path / "model.yaml").write_text("a: 1\n")
    config = load_population(path)
    assert config.controllers[1] == f"offset-free-lqg:{tmp_path / 'model.yaml'}"
    before = fingerprint(config)
    (tmp_path / "model.yaml").write_text("a: 2\n")
    assert fingerprint(config) != before


def test_workers_and_a_scheduler_together_are_refused(tmp_path):
    config = tiny_population(tmp_path, trials=1)
    with pytest.raises(ConfigError, match="not both"):
        sweep(config, tmp_path / "mc", workers=2, scheduler="tcp://127.0.0.1:1")


def test_an_unreachable_scheduler_is_one_line(tmp_path, capsys):
    population = tiny_population_file(tmp_path)
    args = [*command_args(population, tmp_path / "mc", workers=None), "--scheduler", "nonsense"]
    assert main(args) == 2
    assert "--scheduler nonsense: cannot connect" in capsys.readouterr().err


def test_several_seeds_per_patient_give_a_row_per_run_and_resume_by_trial(tmp_path):
    config = tiny_population(tmp_path, trials=2, seeds_per_patient=2)
    summary = sweep(config, tmp_path / "mc", workers=1)
    _, rows = read_trial_rows(tmp_path / "mc" / "trials.csv")
    assert [(r["trial"], r["run"], r["controller"]) for r in rows] == [
        (t, run, c) for t in range(2) for run in range(2) for c in config.controllers
    ]
    assert summary["per_controller"]["paper-lqg"]["runs"] == 4
    first, second = (r for r in rows if r["trial"] == 1 and r["controller"] == "paper-lqg")
    assert first["head_mass_kg"] == second["head_mass_kg"] and first["seed"] != second["seed"]
    one_seed = sweep(dataclasses.replace(config, seeds_per_patient=1), tmp_path / "one", workers=1)
    assert one_seed["per_controller"]["paper-lqg"]["runs"] == 2
    _, single = read_trial_rows(tmp_path / "one" / "trials.csv")
    assert single == [r for r in rows if r["run"] == 0]  # run 0 is the same with more seeds
    grown = sweep(config, tmp_path / "one", workers=1)  # a second seed into the same folder
    assert grown["sweep"]["run_now"] == 2
    assert table_bytes(tmp_path / "one") == table_bytes(tmp_path / "mc")


def test_a_table_no_sweep_claims_is_refused(tmp_path):
    config = tiny_population(tmp_path, trials=1)
    (tmp_path / "mc").mkdir()
    (tmp_path / "mc" / "trials.csv").write_text("trial,run\n0,0\n")
    with pytest.raises(ConfigError, match="no sweep.json saying which sweep made it"):
        sweep(config, tmp_path / "mc", workers=1)
    assert sweep(config, tmp_path / "mc", workers=1, restart=True)["sweep"]["run_now"] == 1


def test_two_threads_of_one_dask_worker_give_the_same_rows(tmp_path):
    """Each thread builds its own loops: no Context or Diagram is shared between trials."""
    distributed = pytest.importorskip("distributed")
    config = tiny_population(tmp_path, trials=4)
    sweep(config, tmp_path / "one", workers=1)
    with local_cluster(distributed, tmp_path, workers=1, threads=2) as cluster:
        sweep(config, tmp_path / "threads", scheduler=cluster.scheduler_address)
    assert table_bytes(tmp_path / "threads") == table_bytes(tmp_path / "one")


def test_what_the_controller_starts_from_is_the_same_for_every_patient(tmp_path, monkeypatch):
    """Through the sweep's own path (simulate_loop, SetRandomContext, the writes), at t = 0."""
    import maskless.diagrams.simulation as simulation

    config = tiny_population(tmp_path)
    runner = TrialRunner(config)
    seen = {}

    class StoppedAtStartError(Exception):
        pass

    class Recording(simulation.Simulator):
        def Initialize(self):  # noqa: N802 (Drake's name)
            context = self.get_context()
            diagram = self.get_system()
            for system in diagram.GetSystems():
                name = system.get_name()
                if name.startswith(("offset_free_lqg", "paper_lqg")):
                    found = _state_and_parameters(diagram.GetSubsystemContext(system, context))
                    seen.setdefault(name, []).append(found)
            raise StoppedAtStartError

    monkeypatch.setattr(simulation, "Simulator", Recording)
    for trial in (0, 1, 2):
        patient = dataclasses.replace(runner.patient(trial), seed=0)  # the same noise draws
        for controller in config.controllers:
            with pytest.raises(StoppedAtStartError):
                runner.simulate(patient, controller)
    assert seen and all(found.count(found[0]) == 3 for found in seen.values())
