"""Open-loop excitation runs: recorded currents (one valve or two), equilibrium, clipping, flags."""

import dataclasses
import json
import math

import numpy as np
import pytest
from two_valve_recordings import recorded_currents

from maskless.diagrams.cli import main
from maskless.diagrams.excitation_design import plan_excitation
from maskless.diagrams.excitation_run import (
    ExcitationRequest,
    build_excitation_loop,
    format_excitation_summary,
    sequential_design,
)
from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.simulation import simulate_loop
from maskless.diagrams.valve_level_experiment import SequentialDesign
from maskless.errors import ConfigError
from maskless.recording import (
    read_camera_frames,
    read_leading_metadata,
    read_recording,
)
from maskless.systems.control.excitation import (
    MULTILEVEL_HOLD_S,
    MULTILEVEL_LEVELS,
    ExcitationSignal,
    multilevel_prbs,
    prbs,
    uniform_white_noise,
)
from maskless.systems.control.valve_level_design import TOP_CURRENT_A, random_level_currents
from maskless.systems.control.valve_pair_excitation import outlet_seed
from maskless.systems.plant.pneumatic_design import linearize_pneumatic_plant
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import equilibrium_state

PERIOD_S = 1.0 / 15.0


def test_the_recorded_command_is_the_designed_signal():
    config = load_scenario()
    config.duration_s = 5.0
    values = np.linspace(0.07, 0.16, 75)
    signal = ExcitationSignal(np.arange(75) * PERIOD_S, values, PERIOD_S, "ramp")
    loop = build_excitation_loop(config, signal)
    assert loop.diagram.get_name() == "pneumatic_excitation"
    run = simulate_loop(loop, config)
    command = run.signals["inlet_valve_current_a"]
    # Logged at the signal's period: sample k holds the k-th value.
    np.testing.assert_array_equal(command.values[0][:75], values[: command.values.shape[1]])
    assert np.all(run.signals["outlet_valve_current_a"].values == 0.0)
    # Nothing is commanded: the reference stays at the resting height.
    reference = run.signals["reference_head_height_m"].values[0]
    assert np.all(reference == pytest.approx(loop.start_height_m))


def test_open_loop_head_settles_at_the_plants_equilibrium_for_each_current():
    config = load_scenario()
    config.duration_s = 45.0  # five of the slowest time constants (~9 s at full inlet)
    p = config.pneumatic
    # The head starts at 6 mm of lift (about 118 mA). Valve hysteresis: a spool coming down
    # stops half a play band above its coil current, one coming up half a band below.
    play_a = p.inlet.play_half_width_a
    for current_a, spool_a in ((0.10, 0.10 + play_a), (0.15, 0.15 - play_a)):
        signal = ExcitationSignal([0.0, PERIOD_S], [current_a, current_a], PERIOD_S, "step")
        run = simulate_loop(build_excitation_loop(config, signal), config)
        final_m = run.signals["head_height_m"].values[0][-1]
        steady_m = p.rest_head_height_m + equilibrium_state(p, spool_a, 0.0)[LIFT]
        start_m = run.closed_loop.start_height_m
        # Within 2 % of the way from the start to the steady height (exp(-5) < 1 %).
        assert final_m == pytest.approx(steady_m, abs=0.02 * abs(steady_m - start_m))


def test_designed_levels_targeted_holds_last_the_shortest_hold_asked_for():
    # The Hammerstein fit's advice on a slow plant is "hold levels at least N s": a user who
    # asks for it with --hold gets it in the targeted stretch too, not only in the random levels.
    def design(hold_s=None):
        request = ExcitationRequest("designed-levels", valve_drive="split-range", hold_s=hold_s)
        return sequential_design(request)

    assert design() == SequentialDesign()
    assert design((5.0, 30.0)).hold_s == SequentialDesign.hold_s
    assert design((87.0, 130.0)) == dataclasses.replace(SequentialDesign(), hold_s=87.0)


def test_request_refuses_an_unknown_signal_naming_the_flag_it_came_from():
    with pytest.raises(ConfigError, match="signal 'chirp': expected one of uniform"):
        ExcitationRequest(signal="chirp")
    with pytest.raises(ConfigError, match="--signal 'chirp'"):
        ExcitationRequest(signal="chirp", labels={"signal": "--signal"})


def test_uniform_noise_std_is_a_over_root_3_and_recording_has_simulate_topics(tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--signal", "uniform", "--amplitude", "50", "--duration", "120"]
    assert main([*args, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    # Eq. 23: sigma = A / sqrt(3); 1800 samples estimate it within a few per cent.
    assert summary["uniform_theoretical_std_ma"] == pytest.approx(50 / math.sqrt(3))
    assert summary["std_ma"] == pytest.approx(50 / math.sqrt(3), rel=0.05)
    recording = read_recording(out / "run.mcap")
    _, current = recording.topic_arrays("/controller/command", "inlet_valve_current_a")
    # The log also holds the instant the run ends, when the last sample is still held.
    current = current[: summary["samples"]]
    deviation = current - current.mean()
    crest = np.max(np.abs(deviation)) / np.sqrt(np.mean(deviation**2))
    assert summary["applied_crest_factor"] == pytest.approx(crest, rel=1e-9)
    # A long uniform sample peaks near A = sqrt(3) sigma: its crest factor is close to sqrt(3).
    assert crest == pytest.approx(math.sqrt(3), rel=0.03)
    simulate_out = tmp_path / "sim"
    assert main(["simulate", "--duration", "2", "--out", str(simulate_out)]) == 0
    # Every topic of a closed-loop run but the safety supervisor's: no controller, no supervisor.
    simulated = set(read_recording(simulate_out / "run.mcap").messages)
    assert set(recording.messages) == simulated - {"/safety/status"}
    assert (out / "run.png").stat().st_size > 10_000


def test_excitation_beyond_the_valve_range_is_clipped(tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--signal", "prbs", "--amplitude", "50", "--offset", "150"]
    assert main([*args, "--duration", "30", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    recording = read_recording(out / "run.mcap")
    _, current = recording.topic_arrays("/controller/command", "inlet_valve_current_a")
    current = current[: summary["samples"]]
    # Half the PRBS's levels (200 mA) exceed the 165 mA saturation and are clipped to it.
    assert current.max() == pytest.approx(0.165)
    assert summary["clipped_fraction"] == pytest.approx(np.mean(current == current.max()))
    assert 0.3 < summary["clipped_fraction"] < 0.7


def test_bad_arguments_are_refused(tmp_path, capsys):
    out = tmp_path / "ex"
    assert main(["excite", "--duration", "-1", "--out", str(out)]) == 2
    assert "--duration -1.0: expected a positive number of seconds" in capsys.readouterr().err
    assert main(["excite", "--offset", "1000", "--out", str(out)]) == 2
    assert "nothing of the excitation is left" in capsys.readouterr().err
    assert main(["excite", "--signal", "multisine", "--band", "5:9", "--out", str(out)]) == 2
    assert "--band 5:9: expected 0 < LOW <= HIGH < the Nyquist frequency, 7.5 Hz" in (
        capsys.readouterr().err
    )
    assert main(["excite", "--clock-periods", "0", "--out", str(out)]) == 2
    assert "--clock-periods 0: expected 1 or more samples per bit" in capsys.readouterr().err
    assert main(["excite", "--signal", "prbs", "--clock-periods", "9000", "--out", str(out)]) == 2
    assert "--clock-periods 9000: expected 1 to 4500" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["excite", "--band", "1-2"])
    assert "LOW:HIGH" in capsys.readouterr().err
    assert not out.exists()


def test_excite_with_rendered_cameras_records_their_frames(tmp_path, capsys):
    out = tmp_path / "rendered"
    args = ["excite", "--signal", "prbs", "--duration", "2", "--sensors", "rendered"]
    assert main([*args, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (out / "frames.png").stat().st_size > 10_000
    assert summary["files"]["frames"] == str(out / "frames.png")
    frames = read_camera_frames(out / "run.mcap")
    assert sorted(frames) == ["kinect_v1", "kinect_v2"]


def test_independent_multilevel_records_each_valves_own_signal(tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--valve-drive", "independent", "--signal", "multilevel", "--seed", "4"]
    args += ["--hold", "0.5:3", "--duration", "20", "--out", str(out), "--json"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    currents = recorded_currents(out, summary["samples"])
    # Each valve's levels span its whole range, 0 to 165 mA (assets/pneumatic.yaml), designed
    # here directly: the inlet from the run's seed, the outlet from its own.
    expected = [
        multilevel_prbs(0.0825, 20.0, PERIOD_S, seed, offset=0.0825, hold_s=(0.5, 3.0)).values
        for seed in (4, outlet_seed(4))
    ]
    np.testing.assert_array_equal(currents, np.column_stack(expected))
    for column, valve in enumerate(("inlet", "outlet")):
        reported = summary["valves"][valve]
        assert reported["std_ma"] == pytest.approx(1e3 * np.std(currents[:, column]), rel=1e-12)
        assert reported["range_ma"] == pytest.approx(
            [1e3 * currents[:, column].min(), 1e3 * currents[:, column].max()], rel=1e-12
        )
        assert reported["clipped_fraction"] == 0.0
    assert summary["valve_drive"] == "independent" and summary["signal"] == "multilevel"


def test_independent_uniform_is_clipped_to_each_valves_range(tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--valve-drive", "independent", "--offset", "140", "--amplitude", "50"]
    assert main([*args, "--duration", "30", "--seed", "2", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    currents = recorded_currents(out, summary["samples"])
    for column, (valve, seed) in enumerate((("inlet", 2), ("outlet", outlet_seed(2)))):
        designed = uniform_white_noise(0.050, 30.0, PERIOD_S, seed, offset=0.140).values
        np.testing.assert_array_equal(currents[:, column], np.clip(designed, 0.0, 0.165))
        clipped = np.count_nonzero(designed > 0.165) / designed.size
        assert summary["valves"][valve]["clipped_fraction"] == clipped
        # A quarter of U(90, 190) mA lies above 165 mA.
        assert clipped == pytest.approx(0.25, abs=0.05)


def test_split_range_never_opens_both_valves_and_recombines(tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--valve-drive", "split-range", "--amplitude", "120", "--seed", "5"]
    assert main([*args, "--duration", "30", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    inlet, outlet = recorded_currents(out, summary["samples"]).T
    # About the split (the inlet's 60 mA starting current), the command range -45 to 165 mA.
    assert summary["offset_ma"] == pytest.approx(60.0)
    command = uniform_white_noise(0.120, 30.0, PERIOD_S, 5, offset=0.060).values
    assert not np.any((inlet > 0.060) & (outlet > 0.060))
    # The outlet's 60-165 mA stands for commands from 60 mA down to -45 mA.
    recombined = np.where(inlet >= 0.060, inlet, 0.060 - (outlet - 0.060))
    np.testing.assert_allclose(recombined, np.clip(command, -0.045, 0.165), rtol=0, atol=1e-6)
    assert summary["valves"]["inlet"]["clipped_fraction"] == np.mean(command > 0.165)
    assert summary["valves"]["outlet"]["clipped_fraction"] == np.mean(command < -0.045)
    text = format_excitation_summary({**summary, "files": {}})
    assert "inlet and outlet (one split-range command)" in text
    assert f"outlet: 0.0-165.0 mA, std {summary['valves']['outlet']['std_ma']:.2f} mA" in text


@pytest.mark.parametrize(
    "fields, message",
    [
        ({"valve_drive": "both"}, "valve_drive 'both': expected one of inlet, independent"),
        (
            {"valve_drive": "independent", "signal": "multisine"},
            "valve_drive 'independent': expected inlet or split-range with a multisine",
        ),
        ({"levels": 1}, "levels 1: expected 2 or more levels"),
        ({"hold_s": (0.0, 1.0)}, r"hold_s \(0.0, 1.0\): expected SHORTEST:LONGEST seconds"),
        ({"hold_s": (3.0, 1.0)}, r"hold_s \(3.0, 1.0\): expected SHORTEST:LONGEST seconds"),
        ({"amplitude_a": 0.0}, "amplitude_a 0.0: expected a positive current"),
    ],
)
def test_request_refuses_malformed_two_valve_and_multilevel_fields(fields, message):
    with pytest.raises(ConfigError, match=message):
        ExcitationRequest(**fields)


def test_cli_names_the_flag_of_a_malformed_two_valve_or_multilevel_field(tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--valve-drive", "independent", "--signal", "multisine", "--out", str(out)]
    assert main(args) == 2
    assert "--valve-drive 'independent': expected inlet or split-range" in capsys.readouterr().err
    assert main(["excite", "--signal", "multilevel", "--hold", "0.01:0.05", "--out", str(out)]) == 2
    assert "--hold 0.01:0.05: expected holds of at least one sample" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["excite", "--valve-drive", "both"])
    assert "invalid choice: 'both'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["excite", "--hold", "1-2"])
    assert "SHORTEST:LONGEST" in capsys.readouterr().err
    assert not out.exists()


def test_multilevel_defaults_fit_the_pneumatic_plants_time_constants():
    p = load_scenario().pneumatic
    inlet = p.inlet

    def slow_time_constant_s(current_a):
        a, _, _ = linearize_pneumatic_plant(p, current_a)
        return max(-1.0 / np.linalg.eigvals(a).real)

    shortest_s, longest_s = MULTILEVEL_HOLD_S
    # Holds at the top level can settle (four time constants), the shortest outlasts the fastest.
    assert longest_s >= 4 * slow_time_constant_s(inlet.saturation_current_a)
    assert shortest_s >= slow_time_constant_s(inlet.starting_current_a + 0.002)
    # Over the whole range the levels are wider apart than the hysteresis band, and some lie
    # below the starting current.
    levels = np.linspace(0.0, inlet.saturation_current_a, MULTILEVEL_LEVELS)
    assert np.diff(levels)[0] > 2 * inlet.hysteresis_fraction * inlet.current_span_a
    assert np.count_nonzero(levels < inlet.starting_current_a) == 4


def test_independent_prbs_gives_the_outlet_the_inlets_sequence_half_a_period_later():
    config = load_scenario()
    request = ExcitationRequest(signal="prbs", valve_drive="independent", duration_s=60.0)
    plan = plan_excitation(config, request)
    # The default centre of each valve, mid-way between 60 and 165 mA, +- 50 mA.
    inlet = prbs(0.050, 60.0, PERIOD_S, config.random_seed, offset=0.1125)
    outlet = prbs(0.050, 60.0, PERIOD_S, config.random_seed, offset=0.1125, half_period_shift=True)
    np.testing.assert_array_equal(plan.inlet.values, inlet.values)
    np.testing.assert_array_equal(plan.outlet.values, outlet.values)
    assert plan.designed_outlet is not None and plan.clipped == {"inlet": 0.0, "outlet": 0.0}
    # Uncorrelated at the lags a model spans (here up to 10 s): a shorter shift would peak there.
    a, b = inlet.values - inlet.values.mean(), outlet.values - outlet.values.mean()
    cross = np.correlate(a, b, mode="full")[a.size - 1 - 150 : a.size + 150] / np.dot(a, a)
    assert np.max(np.abs(cross)) < 0.15


def test_a_split_range_command_clipping_leaves_nothing_of_is_refused():
    config = load_scenario()
    # The command range is -45 to 165 mA (one inlet span below the split to saturation): all of
    # 1000 +- 50 mA lies above it, so both valves would hold still.
    request = ExcitationRequest(valve_drive="split-range", offset_a=1.0, duration_s=30.0)
    with pytest.raises(ConfigError, match="split-range command's .* nothing of the excitation"):
        plan_excitation(config, request)
    # The same +- 50 mA about 190 mA reaches back into the range: the inlet moves, the outlet not.
    plan = plan_excitation(config, dataclasses.replace(request, offset_a=0.190))
    assert np.ptp(plan.inlet.values) > 0.0 and np.ptp(plan.outlet.values) == 0.0


@pytest.mark.parametrize("drive", ["split-range", "independent"])
def test_valve_levels_records_the_benchmarks_level_design(drive, tmp_path, capsys):
    out = tmp_path / "ex"
    args = ["excite", "--valve-drive", drive, "--signal", "valve-levels", "--seed", "3"]
    args += ["--hold", "0.5:3", "--duration", "20", "--out", str(out), "--json"]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    currents = recorded_currents(out, summary["samples"])
    # The levels of benchmarks/hammerstein.py's design, from the run's seed, applied unclipped
    # (past saturation each valve is fully open whatever the current).
    arrangement = drive.replace("-", "_")
    expected = random_level_currents(
        summary["samples"], PERIOD_S, (TOP_CURRENT_A,) * 2, (0.5, 3.0), 3, arrangement
    )
    np.testing.assert_array_equal(currents, expected.T)
    if drive == "split-range":
        assert not np.any((currents[:, 0] > 0) & (currents[:, 1] > 0))
    assert summary["signal"] == "valve-levels"


def test_only_a_designed_recording_says_the_part_to_fit(tmp_path):
    out = tmp_path / "ex"
    args = ["excite", "--valve-drive", "split-range", "--signal", "valve-levels"]
    assert main([*args, "--hold", "0.5:3", "--duration", "20", "--out", str(out)]) == 0
    assert read_leading_metadata(out / "run.mcap") == {}


@pytest.mark.parametrize(
    "signal, fields, message",
    [
        (
            "designed-levels",
            {"valve_drive": "independent"},
            "valve_drive 'independent': expected split-range with designed-levels",
        ),
        (
            "designed-levels",
            {"valve_drive": "split-range", "amplitude_a": 0.05},
            "amplitude_a 0.05: expected none with designed-levels",
        ),
    ],
)
def test_designed_levels_refuse_what_the_design_does_not_take(signal, fields, message):
    with pytest.raises(ConfigError, match=message):
        ExcitationRequest(signal=signal, **fields)


@pytest.mark.parametrize(
    "fields, message",
    [
        ({}, "valve_drive 'inlet': expected split-range or independent with valve-levels"),
        ({"valve_drive": "independent", "amplitude_a": 0.05}, "amplitude_a 0.05: expected none"),
        ({"valve_drive": "split-range", "offset_a": 0.1}, "offset_a 0.1: expected none"),
    ],
)
def test_valve_levels_refuses_what_its_design_does_not_take(fields, message):
    with pytest.raises(ConfigError, match=message):
        ExcitationRequest(signal="valve-levels", **fields)
