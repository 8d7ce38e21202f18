"""`maskless excite` on both valves, then `maskless identify --method hammerstein` on the run."""

import json

import pytest
from two_valve_recordings import validation_fit

from maskless.analysis.identification.hammerstein import minimum_samples
from maskless.analysis.identification.model_file import load_identified_model
from maskless.diagrams import hammerstein_run
from maskless.diagrams.cli import main
from maskless.diagrams.hammerstein_run import (
    MAPS_EXPLAIN_VERDICT,
    format_hammerstein_report,
    hammerstein_verdict,
)
from maskless.systems.hammerstein_model import HammersteinModel


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("excite")
    argv = ["excite", "--signal", "multilevel", "--valve-drive", "independent"]
    assert main([*argv, "--duration", "600", "--hold", "2:20", "--out", str(out)]) == 0
    return out / "run.mcap"


def test_identify_hammerstein_writes_a_model_the_plants_load_and_a_report(
    recording, tmp_path, capsys
):
    capsys.readouterr()
    out = tmp_path / "id"
    argv = ["identify", "--input", str(recording), "--ts", "0.0666667", "--method", "hammerstein"]
    assert main([*argv, "--out", str(out), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    (entry,) = report["models"]
    assert entry["order"] == 2 and set(entry["valves"]) == {"inlet", "outlet"}
    # The inlet lifts the head and the outlet lowers it, as the plant's physics has them.
    assert entry["valves"]["inlet"]["dc_gain"] > 0 > entry["valves"]["outlet"]["dc_gain"]
    low, high = entry["valves"]["inlet"]["starting_current_spread"]
    assert low <= entry["valves"]["inlet"]["starting_current"] <= high
    model = load_identified_model(entry["model_file"])
    assert isinstance(model, HammersteinModel) and model.is_stable()
    assert (out / "hammerstein.png").stat().st_size > 0
    # Judged on the validation part (the default 0.6:1) of the whole record's simulation, from
    # rest at its first currents, by the model as its file loads.
    assert entry["validation_simulation_fit_percent"] == pytest.approx(
        validation_fit(recording, model, "0.6:1"), abs=1e-6
    )


def test_identify_hammerstein_without_plots_draws_none_and_removes_an_earlier_one(
    recording, tmp_path, capsys
):
    out = tmp_path / "id"
    out.mkdir()
    (out / "hammerstein.png").write_bytes(b"an earlier run's plot")
    argv = ["identify", "--input", str(recording), "--ts", "0.0666667", "--method", "hammerstein"]
    assert main([*argv, "--out", str(out), "--no-plots"]) == 0
    assert "plot: none (--no-plots)" in capsys.readouterr().out
    assert json.loads((out / "report.json").read_text())["plot"] is None
    assert not (out / "hammerstein.png").exists()


def test_identify_hammerstein_refuses_a_csv_in_one_line(tmp_path, capsys):
    path = tmp_path / "u.csv"
    path.write_text("1\n2\n3\n")
    argv = ["identify", "--input", str(path), "--ts", "0.1", "--method", "hammerstein"]
    assert main([*argv, "--out", str(tmp_path / "id")]) != 0
    error = capsys.readouterr().err.strip()
    assert "reads a maskless MCAP recording" in error and "\n" not in error


@pytest.mark.parametrize(
    "typed, flag",
    [
        (["--k-step", "3"], "--k-step"),
        (["--k-st", "3"], "--k-step"),  # argparse takes an abbreviation
        (["--detrend", "none"], "--detrend"),
        (["--input-unit", "mA"], "--input-unit"),
        (["--output-unit", "mm"], "--output-unit"),
        (["--initial-state", "zero"], "--initial-state"),
    ],
)
def test_identify_hammerstein_refuses_a_flag_it_would_ignore(typed, flag, tmp_path, capsys):
    argv = ["identify", "--input", "run.mcap", "--ts", "0.1", "--method", "hammerstein", *typed]
    assert main([*argv, "--out", str(tmp_path / "id")]) != 0
    error = capsys.readouterr().err.strip()
    assert f"{flag}: not used by --method hammerstein" in error and "\n" not in error


@pytest.mark.parametrize("method", ["hammerstein", "pem"])
@pytest.mark.parametrize("orders", ["0", "2,-1", "two"])
def test_orders_that_are_not_positive_integers_are_refused_in_one_line(
    method, orders, tmp_path, capsys
):
    # Before, --method hammerstein passed order 0 to the fit: a ValueError traceback.
    argv = ["identify", "--input", "run.mcap", "--ts", "0.1", "--method", method]
    line = _refusal([*argv, "--orders", orders, "--out", str(tmp_path / "id")], capsys)
    assert line.endswith(f"--orders {orders!r}: expected positive integers, e.g. 2,4")


def _refusal(argv, capsys) -> str:
    """The one line a refused `maskless identify` prints (exit code 2)."""
    capsys.readouterr()
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    return line


def test_identify_hammerstein_refuses_a_recording_of_the_inlet_alone(tmp_path, capsys):
    # `maskless excite` drives the inlet only unless told otherwise; before, the fit ended in a
    # ValueError traceback.
    excite = tmp_path / "inlet"
    assert main(["excite", "--signal", "multilevel", "--duration", "60", "--out", str(excite)]) == 0
    out = tmp_path / "id"
    argv = ["identify", "--input", str(excite / "run.mcap"), "--ts", "0.0666667"]
    line = _refusal([*argv, "--method", "hammerstein", "--out", str(out)], capsys)
    assert line.startswith(
        f"maskless identify: error: {excite / 'run.mcap'} /controller/command:"
        "outlet_valve_current_a: the outlet valve's current over the estimation part 0:0.6 is "
        "constant (0 A over all "
    )
    assert line.endswith("maskless excite --valve-drive split-range (or independent)")
    assert not out.exists()


def test_identify_hammerstein_refuses_parts_it_cannot_fit(recording, tmp_path, capsys, monkeypatch):
    argv = ["identify", "--input", str(recording), "--ts", "0.0666667", "--method", "hammerstein"]
    argv += ["--out", str(tmp_path / "id")]
    # Too short for order 2's parameters: before, a ValueError traceback.
    line = _refusal([*argv, "--estimation", "0:100", "--validation", "100:400"], capsys)
    assert line.endswith(
        f"the estimation part 0:100 (given) selects 100 samples; order 2 with two valves needs "
        f"at least {minimum_samples(2, 2)}"
    )
    # A head that stops moving over the validation part (say the cameras lost it and the
    # fusion held its last estimate): no fit is defined there.
    u, y, period_s = hammerstein_run.read_two_valve_record(recording)
    held = y.copy()
    held[y.size // 2 :] = y[y.size // 2]
    monkeypatch.setattr(
        hammerstein_run, "read_two_valve_record", lambda *_, **__: (u, held, period_s)
    )
    line = _refusal(argv, capsys)
    assert line.startswith("maskless identify: error: the validation part 0.6:1 (the default) ")
    assert line.endswith(
        "/fusion/estimate:head_height_m, where the output is constant: no fit is defined on it"
    )
    # A closed loop's outlet: never opened, but for one sample of 1.4e-17 A. Before, that sample
    # passed for variation and the fit made up the outlet's map.
    rounding = u.copy()
    rounding[:, 1] = 0.0
    rounding[0, 1] = 1.4e-17
    monkeypatch.setattr(
        hammerstein_run, "read_two_valve_record", lambda *_, **__: (rounding, y, period_s)
    )
    line = _refusal(argv, capsys)
    assert ":outlet_valve_current_a: the outlet valve's current over the estimation part " in line
    assert "it varies by 1.4e-17 over " in line and "the widest input spans" in line
    assert not (tmp_path / "id").exists()


@pytest.mark.parametrize("method", ["hammerstein", "pem"])
def test_a_cut_off_recording_is_identified_up_to_the_cut_and_reported_so(
    method, recording, tmp_path, capsys
):
    # Before, only a Python warning on stderr said so; the report and its JSON did not.
    cut = tmp_path / "cut.mcap"
    whole = recording.read_bytes()
    cut.write_bytes(whole[: len(whole) // 2])
    # PEM reads the recording's inlet alone, the linear methods' default.
    argv = ["identify", "--input", str(cut), "--ts", "0.0666667", "--method", method]
    capsys.readouterr()
    assert main([*argv, "--no-plots", "--out", str(tmp_path / "id"), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    # A Hammerstein report's warnings are its model's; a linear report's, the record's.
    warnings = report["models"][0]["warnings"] if method == "hammerstein" else report["warnings"]
    assert warnings[0].startswith(f"{cut}: recording is truncated or corrupt")
    assert warnings[0].endswith(": identified from what it held before the cut")
    # A refusal says the cut too: cut within the first 15 s, too little to fit.
    cut.write_bytes(whole[: len(whole) // 40])
    line = _refusal([*argv, "--out", str(tmp_path / "short")], capsys)
    assert f"; {cut}: recording is truncated or corrupt" in line, line


def test_identify_hammerstein_reads_the_fields_it_is_given(recording, tmp_path, capsys):
    # The valves named the other way round: the "inlet" of the fit is the outlet, which lowers
    # the head, so its curve's full value is negative.
    swapped = "/controller/command:outlet_valve_current_a,inlet_valve_current_a"
    argv = ["identify", "--input", str(recording), "--ts", "0.0666667", "--method", "hammerstein"]
    capsys.readouterr()
    assert main([*argv, "--input-column", swapped, "--out", str(tmp_path / "id"), "--json"]) == 0
    (entry,) = json.loads(capsys.readouterr().out)["models"]
    assert entry["valves"]["inlet"]["dc_gain"] < 0 < entry["valves"]["outlet"]["dc_gain"]
    one = "/controller/command:inlet_valve_current_a"
    assert main([*argv, "--input-column", one, "--out", str(tmp_path / "one")]) != 0
    error = capsys.readouterr().err.strip()
    assert "--input-column" in error and "expected TOPIC:FIELD,FIELD" in error
    # The output's field and file are the ones given.
    missing = "/fusion/estimate:no_such_field"
    assert main([*argv, "--output-column", missing, "--out", str(tmp_path / "two")]) != 0
    assert "no_such_field" in capsys.readouterr().err
    csv = tmp_path / "y.csv"
    csv.write_text("1\n2\n")
    assert main([*argv, "--output", str(csv), "--out", str(tmp_path / "three")]) != 0
    assert f"--output {csv}: --method hammerstein reads" in capsys.readouterr().err


def test_the_report_says_where_a_start_came_from_and_the_play_it_found():
    valve = {
        "starting_current_spread": [0.058, 0.062],
        "highest_current_in_record": 0.19,
        "saturation_current": 0.165,
        "starting_current": 0.06,
        "dc_gain": -0.0019,
    }
    sectioned = {
        **valve,
        "starting_current_from": "a section: its settled levels with the other valve held open",
        "play_half_width": 0.0026,
        "saturation_current_spread": [0.1537, 0.1759],
    }
    report = {
        "recording": "run.mcap",
        "estimation": "0:0.8",
        "estimation_from": "the recording's design",
        "validation": "0.6:1",
        "validation_from": "given",
        "plot": "hammerstein.png",
        "models": [
            {
                "order": 2,
                "validation_simulation_fit_percent": 80.0,
                "linear_validation_simulation_fit_percent": 50.0,
                "verdict": "better than linear",
                "valves": {"inlet": valve, "outlet": sectioned},
                "model_file": "model.yaml",
            }
        ],
    }
    split, _, inlet, outlet = format_hammerstein_report(report).splitlines()[1:5]
    assert split == "  fitted on 0:0.8 (the recording's design), judged on 0.6:1 (given)"
    assert "play" not in inlet and "inlet: starts at 60.0 mA (the record cannot" in inlet
    assert (
        "from a section: its settled levels with the other valve held open, play ±2.6 mA" in outlet
    )
    # A saturation read from settled levels says what the record cannot tell apart too.
    assert "saturates at 165.0 mA (the record cannot tell apart 153.7-175.9 mA)," in outlet
    assert "saturates at 165.0 mA," in inlet
    # A joint search's spread says how close to the best cost its searches had to end, and is
    # where they ended, not a range the record rules out.
    report["models"][0]["valves"]["inlet"] = {**valve, "spread_cost_tolerance": 0.081}
    inlet = format_hammerstein_report(report).splitlines()[3]
    assert "(searches ending within 8.1 % of the best cost ended at " in inlet
    assert "cannot tell apart" not in inlet
    # The fit's warnings are shown, each on its own line, before the model file.
    report["models"][0]["warnings"] = ["the section was fitted as a sum of curves"]
    lines = format_hammerstein_report(report).splitlines()
    assert lines[5] == "    WARNING: the section was fitted as a sum of curves"
    assert lines[6].startswith("    model file")


@pytest.mark.parametrize(
    "fits, begins",
    [
        # 900 s of designed levels on seed 0 (`maskless workflow --method hammerstein
        # --excitation-duration 900`) fitted -79.8 % against the linear model's -135.8 %: once
        # called "the valve maps explain 56.0 points more".
        ((-79.8, -135.8), "the model does not explain the validation part: its simulation "),
        ((49.9, 10.0), "the model does not explain the validation part"),
        ((50.0, 44.0), f"{MAPS_EXPLAIN_VERDICT} 6.0 points"),
        ((79.4, 37.9), f"{MAPS_EXPLAIN_VERDICT} 41.5 points"),
        ((80.0, 77.0), "the valve maps add 3.0 points of validation simulation fit over"),
    ],
)
def test_the_verdict_asks_the_maps_to_explain_the_output_and_to_beat_linear(fits, begins):
    assert hammerstein_verdict(*fits).startswith(begins)
