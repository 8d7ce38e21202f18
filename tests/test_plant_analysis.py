"""maskless analyze: its JSON matches the pure analysis functions; summaries and bad flags."""

import json

import numpy as np
import pytest

from maskless.analysis.operating_range import default_operating_ranges
from maskless.analysis.stability.loop_robustness import analyze_paper_loop, robustness_cases
from maskless.diagrams.cli import build_parser, main
from maskless.diagrams.closed_loop import build_closed_loop
from maskless.diagrams.plant_analysis import offset_free_setup
from maskless.diagrams.scenario import load_scenario
from maskless.systems.control.paper_lqg import paper_lqg


def run_json(capsys, *args):
    assert main(["analyze", *args, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_operating_range_json_matches_the_pure_functions(tmp_path, capsys):
    out = tmp_path / "out"
    report = run_json(capsys, "operating-range", "--points", "5", "--out", str(out))
    assert json.loads((out / "operating_range.json").read_text()) == report
    assert (out / "operating_range.png").stat().st_size > 10_000
    ranges = default_operating_ranges(load_scenario().pneumatic, 5)
    for valve, sweep in ranges.items():
        entry = report["valves"][valve]
        rows = entry["rows"]
        assert len(rows) == 5
        np.testing.assert_allclose([r["current_ma"] for r in rows], 1000 * sweep.currents_a)
        np.testing.assert_allclose([r["lift_mm"] for r in rows], 1000 * sweep.lift_m)
        np.testing.assert_allclose(
            [r["gauge_pressure_kpa"] for r in rows], sweep.gauge_pressure_pa / 1000
        )
        # m/A and mm/mA are the same number.
        np.testing.assert_allclose([r["dc_gain_mm_per_ma"] for r in rows], sweep.dc_gain_m_per_a)
        np.testing.assert_allclose(
            [r["slow_time_constant_s"] for r in rows], sweep.slow_time_constant_s
        )
        assert entry["lift_span_mm"] == pytest.approx(1000 * sweep.lift_span_m)
    inlet = ranges["inlet"]
    assert report["working_range_mm"] == pytest.approx(
        [1000 * inlet.lift_m.min(), 1000 * inlet.lift_m.max()]
    )
    assert report["valves"]["outlet"]["held_current_ma"] == pytest.approx(165.0)


def test_stability_json_matches_the_pure_functions(tmp_path, capsys):
    out = tmp_path / "out"
    args = ["stability", "--lifts", "9", "--mass-factors", "1.2", "--extra-latency-ticks", "1"]
    report = run_json(capsys, *args, "--out", str(out))
    assert json.loads((out / "stability.json").read_text()) == report
    for name in ("stability_paper_lqg", "stability_offset_free_lqg", "stability_margins"):
        assert (out / f"{name}.png").stat().st_size > 10_000

    config = load_scenario()
    model, design = paper_lqg(config.paper)
    paper = analyze_paper_loop(model, design)
    reported = report["paper_lqg"]
    assert reported["peak_loop_gain"] == pytest.approx(paper.peak_loop_gain)
    assert reported["regulator_pole_shift"] == pytest.approx(paper.regulator_pole_shift)
    assert reported["margins"]["gain_margin_db"] == pytest.approx(paper.loop.margins.gain_margin_db)
    assert reported["margins"]["phase_margin_deg"] == "inf"  # |L| never reaches 1
    assert len(reported["closed_loop_poles"]) == 4 and reported["stable"]

    _, allocation, design = offset_free_setup(config)
    cases = robustness_cases(config.pneumatic, allocation, design, [0.009], [1.0, 1.2], [0, 1])
    o = report["offset_free_lqg"]
    assert o["design"]["measurement_delay_ticks"] == design.measurement_delay_samples
    assert o["design"]["operating_lift_mm"] == pytest.approx(9.0)
    # Mass factor 1 and no extra latency are always included.
    assert [(c["mass_factor"], c["extra_latency_ticks"]) for c in o["cases"]] == [
        (1.0, 0),
        (1.0, 1),
        (1.2, 0),
        (1.2, 1),
    ]
    for entry, case in zip(o["cases"], cases, strict=True):
        assert entry["lift_mm"] == pytest.approx(9.0)
        assert entry["head_mass_kg"] == pytest.approx(case.head_mass_kg)
        assert entry["stable"] is case.analysis.stable
        assert entry["max_pole_magnitude"] == pytest.approx(case.analysis.max_pole_magnitude)
        for name in ("gain_margin_db", "phase_margin_deg", "delay_margin_s"):
            assert entry["margins"][name] == pytest.approx(getattr(case.analysis.margins, name))
        assert entry["delay_margin_exceeds_requirement"] is (
            case.analysis.margins.delay_margin_s > 0.1
        )
    assert o["min_delay_margin_s"] == pytest.approx(
        min(c.analysis.margins.delay_margin_s for c in cases)
    )
    assert o["all_stable"] is all(c.analysis.stable for c in cases)


def test_stability_analyses_the_controller_the_closed_loop_runs():
    config = load_scenario()
    _, _, design = offset_free_setup(config)
    running = build_closed_loop(config, record=False).design
    for name in ("K", "M", "augmented_A", "augmented_C"):
        np.testing.assert_array_equal(getattr(design, name), getattr(running, name))
    assert design.measurement_delay_samples == running.measurement_delay_samples


def test_human_summaries(tmp_path, capsys):
    assert main(["analyze", "operating-range", "--points", "3", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "Working range" in text and "mm/mA" in text and "operating_range.png" in text
    args = ["analyze", "stability", "--lifts", "5", "--mass-factors", "0.8"]
    assert main([*args, "--extra-latency-ticks", "2", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "nearly open" in text and "delay margin" in text and "all stable" in text


@pytest.mark.parametrize(
    "args, flag",
    [
        (["operating-range", "--points", "1"], "--points"),
        (["stability", "--lifts", "9,x"], "--lifts"),
        (["stability", "--lifts", "30"], "--lifts"),
        (["stability", "--mass-factors", "-0.5"], "--mass-factors"),
        (["stability", "--mass-factors", "100"], "--mass-factors"),  # no steady state at all
        (["stability", "--extra-latency-ticks", "-1"], "--extra-latency-ticks"),
        (["stability", "--extra-latency-ticks", "1.5"], "--extra-latency-ticks"),
    ],
)
def test_bad_arguments_exit_2_naming_the_flag(tmp_path, capsys, args, flag):
    out = tmp_path / "out"
    assert main(["analyze", *args, "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("maskless analyze: error: ") and flag in error
    assert not out.exists()


def test_missing_config_and_unknown_analysis_are_refused(tmp_path, capsys):
    missing = tmp_path / "none.yaml"
    assert main(["analyze", "stability", "--config", str(missing), "--out", str(tmp_path)]) == 2
    assert "config file not found" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_info:
        main(["analyze", "bode"])
    assert exit_info.value.code == 2
    assert "invalid choice: 'bode'" in capsys.readouterr().err


def test_analyze_is_a_listed_command():
    help_text = build_parser(["--help"]).format_help()
    assert "analyze" in help_text


@pytest.mark.parametrize("leak_factor", [0.01, 0.1, 10.0])
def test_a_sealed_or_a_leaky_bladder_is_analysed_and_simulated_not_a_traceback(
    tmp_path, capsys, leak_factor
):
    nominal = load_scenario().pneumatic.leak_sonic_conductance_m3_s_pa
    config = tmp_path / "bladder.yaml"
    config.write_text(f"pneumatic:\n  leak_sonic_conductance_m3_s_pa: {nominal * leak_factor:e}\n")
    out = tmp_path / "out"
    assert main(["analyze", "operating-range", "--config", str(config), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    report = json.loads(
        (out / "operating_range.json").read_text(),
        parse_constant=lambda name: pytest.fail(f"{name} in the report: not JSON"),
    )
    inlet = report["valves"]["inlet"]["rows"]
    past = [row for row in inlet if row["dc_gain_mm_per_ma"] is None]
    # A well-sealed bladder fills towards the supply and pushes the head past its travel (onto
    # the model's stop); a leaky one never gets there.
    assert bool(past) == (leak_factor < 1)
    assert ("past the travel: held by the stop" in text) == (leak_factor < 1)
    travel_mm = (-8.0, 40.0)  # pneumatic.yaml's min_lift_m and max_lift_m
    assert all(row["lift_mm"] >= travel_mm[1] for row in past)
    low, high = report["working_range_mm"]
    assert travel_mm[0] <= low <= high <= travel_mm[1]
    args = ["simulate", "--config", str(config), "--duration", "3", "--out", str(tmp_path / "s")]
    assert main(args) == 0


@pytest.mark.parametrize(
    "args, message",
    [
        (["operating-range", "--points", "100000"], "--points 100000: expected 2 to 1000"),
        (["stability", "--extra-latency-ticks", "1000"], "--extra-latency-ticks 1000 x"),
        (["stability", "--mass-factors", "0.001"], "--mass-factors 0.001: head_mass_kg"),
    ],
)
def test_implausible_analysis_flags_exit_2_in_one_line(tmp_path, capsys, args, message):
    assert main(["analyze", *args, "--out", str(tmp_path / "a")]) == 2
    error = capsys.readouterr().err
    assert message in error and error.count("\n") == 1 and "Traceback" not in error
    assert not (tmp_path / "a").exists()
