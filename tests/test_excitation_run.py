"""Open-loop excitation runs: the recorded signal, the plant's equilibrium, clipping, bad flags."""

import json
import math

import numpy as np
import pytest

from maskless.diagrams.cli import main
from maskless.diagrams.excitation_run import ExcitationRequest, build_excitation_loop
from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.simulation import simulate_loop
from maskless.errors import ConfigError
from maskless.recording import read_camera_frames, read_recording
from maskless.systems.control.excitation import ExcitationSignal
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
