"""maskless analyze faults: the fault matrix runs each case, never crashes, says what it found."""

import dataclasses
import json

import pytest

import maskless.diagrams.fault_matrix as fault_matrix
from maskless.analysis.trial_table import read_trial_rows
from maskless.diagrams.cli import main
from maskless.diagrams.fault_matrix import (
    COLUMNS,
    FaultMatrixRequest,
    fault_cases,
    run_fault_matrix,
)
from maskless.diagrams.scenario import load_scenario
from maskless.errors import ConfigError


def request(tmp_path, cases, seeds=1, **changes):
    scenario = load_scenario(duration_s=40.0)
    return FaultMatrixRequest(
        out=tmp_path / "faults",
        scenario=dataclasses.replace(scenario, **changes),
        cases=cases,
        seeds=seeds,
        workers=1,
        progress=False,
    )


def test_every_shipped_example_is_a_case_and_nominal_has_no_fault():
    cases = fault_cases()
    assert cases["nominal"] == {}
    assert {"both-cameras-lost", "camera-frozen", "seam-leak", "missed-ticks"} <= set(cases)
    assert all(cases[name] for name in cases if name != "nominal")


def test_an_unknown_case_is_refused_naming_the_known_ones():
    with pytest.raises(ConfigError, match="no fault example 'camera-melted'.*both-cameras-lost"):
        fault_cases(("camera-melted",))


def test_a_small_matrix_writes_its_rows_summary_and_plot(tmp_path):
    summary = run_fault_matrix(request(tmp_path, ("nominal", "faults/camera-frozen.yaml")))
    out = tmp_path / "faults"
    columns, rows = read_trial_rows(out / "faults.csv")
    assert tuple(columns) == COLUMNS
    assert [(r["case"], r["seed"]) for r in rows] == [("nominal", 0), ("camera-frozen", 0)]
    nominal, frozen = rows
    assert nominal["detected_by"] is None and nominal["fault_start_s"] is None
    assert nominal["beam_on_while_off_target_s"] == 0.0
    # The frozen camera repeats one reading to the bit: the stuck check (1 s) leaves it out and
    # the supervisor latches camera_excluded; the loop goes on with the other camera.
    assert frozen["detected_by"] in ("kinect_v1.stuck", "fusion.fewer_tracks")  # the same tick
    assert frozen["detection_latency_s"] <= 1.0
    assert frozen["safe_state_reason"] == "camera_excluded"
    assert frozen["p95_abs_error_mm"] < 1.5
    assert json.loads((out / "faults.json").read_text())["cases"].keys() == {
        "nominal",
        "camera-frozen",
    }
    assert (out / "faults.png").stat().st_size > 10_000
    assert summary["all_targets_met"]


def test_a_run_that_raises_is_a_row_naming_why_and_a_missed_target(tmp_path, monkeypatch):
    real = fault_matrix.simulate

    def simulate(scenario):
        if scenario.faults:
            raise RuntimeError("the plant exploded")
        return real(scenario)

    monkeypatch.setattr(fault_matrix, "simulate", simulate)
    summary = run_fault_matrix(request(tmp_path, ("nominal", "camera-biased")))
    _, rows = read_trial_rows(tmp_path / "faults" / "faults.csv")
    assert rows[1]["error"].startswith("RuntimeError: the plant exploded")
    assert summary["cases"]["camera-biased"]["errors"] == 1
    assert not summary["all_targets_met"]


def test_the_command_exits_0_when_the_targets_are_met_and_refuses_bad_flags(tmp_path, capsys):
    out = tmp_path / "m"
    args = ["analyze", "faults", "--seeds", "1", "--duration", "30", "--workers", "1"]
    assert main([*args, "--faults", "nominal", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "Fault matrix: 1 cases x 1 seeds" in text and "met " in text
    assert main([*args, "--faults", "nominal", "--out", str(out)]) == 2  # a matrix is there
    assert "--overwrite" in capsys.readouterr().err
    assert main([*args, "--faults", "nope", "--out", str(tmp_path / "n")]) == 2
    assert main(["analyze", "faults", "--seeds", "0", "--out", str(tmp_path / "z")]) == 2
