"""The workflow end to end: identified gain against the plant's linearisations; the loop tracks."""

import argparse
import dataclasses
import json
import shlex
from pathlib import Path

import numpy as np
import pytest

from maskless.analysis.identification.model_file import load_identified_model
from maskless.diagrams import workflow as workflow_module
from maskless.diagrams.cli import main
from maskless.diagrams.commands import excite
from maskless.diagrams.excitation_design import ExcitationRequest
from maskless.diagrams.hammerstein_run import MAPS_EXPLAIN_VERDICT, hammerstein_verdict
from maskless.diagrams.scenario import load_scenario, shipped_presets
from maskless.diagrams.simulation import simulate_to_files
from maskless.diagrams.workflow import (
    HAMMERSTEIN_EXCITATION,
    advised_excitation,
    excite_command,
    run_workflow,
)
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.plant.pneumatic_design import linearize_pneumatic_plant
from maskless.systems.units import a_to_ma


# Order 2 is the paper's; order 3's fit carries a non-minimum-phase zero, the case where a filter
# that trusted the states less than the identified noise model says chattered the valves.
@pytest.fixture(scope="module", params=[2, 3], ids=["order2", "order3"])
def workflow(request, tmp_path_factory):
    out = tmp_path_factory.mktemp("workflow")
    lines = []
    result = run_workflow(out, order=request.param, closed_loop_s=60.0, echo=lines.append)
    return out, result, lines


# The sequential design of both valves, an hour long as measured; the closed loop as above.
@pytest.fixture(scope="module")
def hammerstein_workflow(tmp_path_factory):
    out = tmp_path_factory.mktemp("hammerstein_workflow")
    lines = []
    result = run_workflow(out, method="hammerstein", closed_loop_s=60.0, echo=lines.append)
    return out, result, lines


def linearised_gain_m_per_a(current_a):
    A, B, C = linearize_pneumatic_plant(load_scenario().pneumatic, current_a)
    return float((C @ np.linalg.solve(-A, B))[0, 0])


def test_identified_gain_lies_within_the_plant_linearisations_over_the_excited_range(workflow):
    # The PRBS swings the inlet over 130 +- 25 mA, where the plant's static gain is nonlinear:
    # the identified (averaged) gain must fall between the linearised gains at the two ends.
    _, result, _ = workflow
    identified = result["identification"]["dc_gain"]
    assert linearised_gain_m_per_a(0.105) < identified < linearised_gain_m_per_a(0.155)
    assert "The input explains the output" in result["identification"]["verdict"]


def test_the_loop_designed_on_the_identified_model_tracks_the_step(workflow):
    out, result, lines = workflow
    tracking = result["closed_loop"]["tracking"]
    assert result["closed_loop"]["controller"] == "offset-free-lqg"
    assert result["closed_loop"]["plant"] == "pneumatic"
    assert tracking["settled"] and tracking["settle_time_s"] < 10.0
    assert tracking["p95_abs_error_mm"] < 0.5 and tracking["overshoot_mm"] < 1.0
    # No chatter: the inlet stays within the currents a 5 mm lift needs, never slammed shut.
    assert result["closed_loop"]["valve_commands"]["inlet_range_ma"][0] > 80.0
    assert [line.split()[1] for line in lines] == ["excite", "identify", "simulate"]
    for stage in ("excitation/run.mcap", "identification/report.json", "closed_loop/run.mcap"):
        assert (out / stage).is_file()


def test_workflow_command_prints_json_and_text(tmp_path, capsys):
    # 5 s ends before the reference step: the text must cope with no overshoot to report.
    args = ["workflow", "--excitation-duration", "200", "--duration", "5"]
    assert main([*args, "--out", str(tmp_path / "a"), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert {"excitation", "identification", "closed_loop"} == result.keys()
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    assert "overshoot n/a (no reference step)" in capsys.readouterr().out


def test_uniform_noise_at_the_frame_rate_gets_a_warning(workflow, tmp_path, capsys):
    # The paper's own excitation leaves the input's effect below the noise (its B ~ 1e-7):
    # the workflow says the design is not to be trusted.
    args = ["--signal", "uniform", "--clock-periods", "1", "--amplitude", "50"]
    argv = ["workflow", *args, "--offset", "112.5", "--duration", "5", "--out", str(tmp_path)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "explains essentially nothing" in text and "WARNING" in text
    assert workflow[1]["identification"]["warnings"] == []


def test_a_moving_patient_gets_the_warning_of_a_model_that_explains_part(tmp_path, capsys):
    # The standard population's patient motion moves the head without the input: the model
    # explains part of the output, which on those patients still designed loops as good as the
    # nominal one (benchmarks/identified_control.py), so the warning says "less certain".
    motion = shipped_presets()["patient_motion"]
    argv = ["workflow", "--config", str(motion), "--duration", "5", "--out", str(tmp_path)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "The input explains part of the output" in text
    assert "WARNING: the identified model explains only part of the output" in text
    assert "not to be trusted" not in text


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--duration", "0"], "--duration 0.0: expected a positive"),
        (["--excitation-duration", "-1"], "--excitation-duration -1.0: expected a positive"),
        (["--order", "0"], "--order 0: expected a model order of at least 1"),
    ],
)
def test_bad_flags_are_refused_before_any_stage_runs(tmp_path, capsys, flags, message):
    out = tmp_path / "wf"
    assert main(["workflow", *flags, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_each_printed_command_redoes_its_stage_byte_for_byte(workflow, capsys):
    redo_each_stage_and_compare(*workflow[::2], capsys)


def test_each_printed_hammerstein_command_redoes_its_stage_byte_for_byte(
    hammerstein_workflow, capsys
):
    redo_each_stage_and_compare(*hammerstein_workflow[::2], capsys)


def redo_each_stage_and_compare(out: Path, lines: list[str], capsys) -> None:
    files = ["excitation/run.mcap", "identification/report.json", "closed_loop/run.mcap"]
    before = {name: (out / name).read_bytes() for name in files}
    for line in lines:
        argv = shlex.split(line)
        assert argv[0] == "maskless" and main(argv[1:]) == 0
    capsys.readouterr()
    for name in files:
        assert (out / name).read_bytes() == before[name], name


@pytest.mark.parametrize(
    "request_",
    [
        ExcitationRequest(signal="uniform"),
        ExcitationRequest(signal="prbs", amplitude_a=0.025, offset_a=0.13, clock_periods=30),
        ExcitationRequest(signal="multilevel", valve_drive="independent", hold_s=(0.5, 20.0)),
        ExcitationRequest(signal="multisine", valve_drive="split-range", band_hz=(0.01, 1.0)),
        HAMMERSTEIN_EXCITATION,
        advised_excitation(HAMMERSTEIN_EXCITATION, 86.2),
    ],
)
def test_the_printed_excite_command_asks_for_the_same_experiment(request_):
    argv = shlex.split(excite_command(request_, 0, None, Path("out")))
    assert argv[:2] == ["maskless", "excite"]
    parser = argparse.ArgumentParser()
    excite.add_arguments(parser)
    assert excite.excitation_request(parser.parse_args(argv[2:])) == request_


def test_the_hammerstein_workflow_finds_the_plants_valve_maps(hammerstein_workflow):
    # The scenario's plant is the reference: the identified starts against the ones it was
    # built with, and the maps must beat the linear model on the held-out part.
    _, result, lines = hammerstein_workflow
    identified = result["identification"]
    plant = load_scenario().pneumatic
    for name, valve in (("inlet", plant.inlet), ("outlet", plant.outlet)):
        found = identified["valves"][name]["starting_current_ma"]
        assert abs(found - a_to_ma(valve.starting_current_a)) < 5.0, name
    assert identified["verdict"].startswith(MAPS_EXPLAIN_VERDICT)
    fits = identified["validation_simulation_fit_percent"]
    assert fits > identified["linear_validation_simulation_fit_percent"] + 5.0
    assert isinstance(load_identified_model(identified["model_file"]), HammersteinModel)
    assert "--method hammerstein --estimation 0:0.8 --validation 0.8:1" in lines[1]


def test_the_loop_opens_the_valves_through_the_identified_maps_and_tracks(hammerstein_workflow):
    _, result, _ = hammerstein_workflow
    closed_loop = result["closed_loop"]
    tracking = closed_loop["tracking"]
    assert tracking["settled"] and tracking["settle_time_s"] < 10.0
    assert tracking["p95_abs_error_mm"] < 0.5 and tracking["overshoot_mm"] < 1.0
    # The inverse of the identified inlet map never asks past that map's saturation, which lies
    # below the nominal plant's (165 mA) here: the commands came through the identified maps.
    saturation_ma = result["identification"]["valves"]["inlet"]["saturation_current_ma"]
    assert saturation_ma < a_to_ma(load_scenario().pneumatic.inlet.saturation_current_a)
    assert closed_loop["valve_commands"]["inlet_range_ma"][1] <= saturation_ma + 1e-9


def test_the_loop_on_the_identified_maps_tracks_as_the_design_on_the_plants_physics_does(
    hammerstein_workflow, tmp_path
):
    # The reference is the design on the nominal plant's own linearisation and inverse, which the
    # identified model can at best match: same plant, seed and step. Designed on the order-2 fit
    # with no process noise on its states, the loop's p95 was 0.451 mm against the reference's
    # 0.162 mm.
    _, result, _ = hammerstein_workflow
    identified = result["closed_loop"]["tracking"]
    nominal_run = simulate_to_files(load_scenario(duration_s=60.0), tmp_path / "nominal")
    nominal = nominal_run["tracking"]
    assert identified["p95_abs_error_mm"] < 1.25 * nominal["p95_abs_error_mm"]
    assert identified["overshoot_mm"] < nominal["overshoot_mm"] + 0.1


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--amplitude", "25"], "--amplitude: not used by --method hammerstein"),
        (["--clock-periods", "30"], "--clock-periods: not used by --method hammerstein"),
        (["--signal", "prbs"], "--signal 'prbs': expected valve-levels or designed-levels"),
    ],
)
def test_the_hammerstein_workflow_refuses_a_single_valve_experiment(
    tmp_path, capsys, flags, message
):
    out = tmp_path / "wf"
    assert main(["workflow", "--method", "hammerstein", *flags, "--out", str(out)]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_the_hammerstein_stage_passes_on_the_fits_warnings_and_a_failed_verdict(
    monkeypatch, tmp_path, hammerstein_workflow
):
    # The stage's own wiring, on a report as `identify --method hammerstein` writes one for a
    # fit that failed (900 s of designed levels on seed 0: -79.8 % against -135.8 %).
    valve = {
        "starting_current": 0.1077,
        "starting_current_spread": [0.1077, 0.1077],
        "starting_current_from": "the joint search",
        "saturation_current": 0.140,
        "saturation_current_spread": None,
        "dc_gain": 0.0178,
    }
    searched = "too few holds settled to read the static curves from them"
    model = {
        "model_file": str(tmp_path / "model.yaml"),
        "verdict": hammerstein_verdict(-79.8, -135.8),
        "valves": {"inlet": valve, "outlet": {**valve, "dc_gain": -0.0084}},
        "validation_simulation_fit_percent": -79.8,
        "linear_validation_simulation_fit_percent": -135.8,
        "poles": [[0.98, 0.0], [0.5, 0.0]],
        "levels_scatter": None,
        "advised_hold_s": 86.2,
        "warnings": [searched],
    }
    report = {"models": [model], "plot": None}
    monkeypatch.setattr(workflow_module, "identify_hammerstein_to_files", lambda *a, **k: report)
    excited = {"files": {"recording": "run.mcap"}, "sample_period_s": 1 / 15}
    identified = workflow_module.identify_recording("hammerstein", excited, 2, tmp_path)
    assert identified["warnings"][0] == searched
    assert "do not explain the held-out part" in identified["warnings"][1]
    # Shown in the text beside a real run's other stages.
    text = workflow_module.format_workflow(
        {**hammerstein_workflow[1], "identification": identified}
    )
    assert "inlet starts at 107.7 mA (its searches ended at 107.7-107.7 mA)" in text
    assert f"WARNING: {searched}" in text and "does not explain the validation part" in text


def test_the_advised_experiment_holds_levels_as_advised_over_twice_the_duration():
    advised = advised_excitation(HAMMERSTEIN_EXCITATION, 86.2)
    assert advised.hold_s == (87.0, 130.5)
    assert advised.duration_s == 2 * HAMMERSTEIN_EXCITATION.duration_s
    # The rest of the experiment is the same.
    assert advised == dataclasses.replace(
        HAMMERSTEIN_EXCITATION, hold_s=advised.hold_s, duration_s=advised.duration_s
    )


class _StoppedAfterIdentifyError(Exception):
    pass


def test_a_fit_that_advises_longer_holds_gets_the_experiment_to_run_printed(
    monkeypatch, tmp_path, hammerstein_workflow
):
    # The workflow's wiring: the identify stage's advice becomes an excite command, echoed and
    # shown with the stages. The stages themselves are stand-ins; the closed loop is not run.
    excited = {"files": {"recording": "run.mcap"}, "sample_period_s": 1 / 15}
    identified = {**hammerstein_workflow[1]["identification"], "advised_hold_s": 86.2}
    monkeypatch.setattr(workflow_module, "excite_to_files", lambda *a, **k: excited)
    monkeypatch.setattr(workflow_module, "identify_recording", lambda *a, **k: identified)

    def stop(**_):
        raise _StoppedAfterIdentifyError

    monkeypatch.setattr(workflow_module, "OffsetFreeLqg", stop)
    lines = []
    with pytest.raises(_StoppedAfterIdentifyError):
        run_workflow(tmp_path, method="hammerstein", echo=lines.append)
    expected = excite_command(
        advised_excitation(HAMMERSTEIN_EXCITATION, 86.2), 0, None, tmp_path / "excitation-advised"
    )
    assert lines[-1] == f"ADVICE: {expected}"
    assert identified["advised_command"] == expected
    text = workflow_module.format_workflow(
        {**hammerstein_workflow[1], "identification": identified}
    )
    assert f"run the experiment again (and identify its record as above): {expected}" in text
