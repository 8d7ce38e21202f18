"""maskless simulate: recording, plot and summary; the streamed recording is the one-shot one.

A run stopped by a signal or killed leaves no process behind and a recording any MCAP reader
reads; a folder holding a run is refused before anything is simulated.
"""

import json
import signal
import subprocess
import sys
import time

import pytest
from camera_frames import face_frame
from mcap.reader import make_reader

from maskless.diagrams.cli import main
from maskless.diagrams.scenario import (
    controller_from_shorthand,
    load_scenario,
    plant_from_shorthand,
)
from maskless.diagrams.simulation import first_and_last_frames, simulate
from maskless.recording import (
    TruncatedRecordingWarning,
    read_camera_frames,
    read_recording,
    write_recording,
)


def test_simulate_writes_recording_plot_and_json_summary(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", "--duration", "6", "--seed", "2", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["duration_s"] == 6.0 and summary["random_seed"] == 2
    assert {"tracking", "estimation", "offset_free_lqg", "timing", "files"} <= summary.keys()
    assert (summary["plant"], summary["controller"]) == ("pneumatic", "offset-free-lqg")
    assert (out / "run.png").stat().st_size > 10_000
    recording = read_recording(out / "run.mcap")
    assert not recording.truncated
    times, _ = recording.topic_arrays("/plant/head_height", "head_height_m")
    assert times[-1] <= 6e9


def test_simulate_prints_a_human_summary(tmp_path, capsys):
    assert main(["simulate", "--duration", "3", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "Tracking" in text and "fused" in text and "run.mcap" in text


def test_paper_flags_reproduce_the_paper_loop(tmp_path, capsys):
    args = ["simulate", "--duration", "3", "--out", str(tmp_path), "--json"]
    assert main([*args, "--plant", "paper", "--controller", "paper-lqg"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert (summary["plant"], summary["controller"]) == ("paper", "paper-lqg")
    assert "paper_model" in summary


def test_unknown_plant_and_missing_model_file_are_refused(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["simulate", "--plant", "pneumatik", "--out", str(out)]) == 2
    assert "--plant 'pneumatik': expected one of pneumatic, paper" in capsys.readouterr().err
    missing = tmp_path / "none.yaml"
    assert main(["simulate", "--controller", f"offset-free-lqg:{missing}", "--out", str(out)]) == 2
    assert "model file not found" in capsys.readouterr().err
    assert not out.exists()


def test_mistyped_config_is_refused_before_anything_runs(tmp_path, capsys):
    config = tmp_path / "bad.yaml"
    config.write_text("cameras:\n  kinect_v2:\n    frame_rate: 30\n")
    out = tmp_path / "out"
    assert main(["simulate", "--config", str(config), "--out", str(out)]) == 2
    error = capsys.readouterr().err
    assert "bad.yaml" in error and "cameras.kinect_v2.frame_rate" in error
    assert "frame_rate_hz" in error
    assert not out.exists()


def test_bad_duration_is_refused(tmp_path, capsys):
    assert main(["simulate", "--duration", "0", "--out", str(tmp_path / "o")]) == 2
    assert "--duration" in capsys.readouterr().err


@pytest.mark.parametrize(
    "plant, controller",
    # The paper's loop logs at two periods (its controller's 0.048 s and the cameras' 1/15 s).
    [("pneumatic", "offset-free-lqg"), ("paper", "paper-lqg")],
)
def test_the_streamed_recording_is_the_one_shot_recording_of_the_same_run(
    tmp_path, plant, controller
):
    # `maskless simulate` writes the recording in batches from a worker while the loop runs.
    args = ["--duration", "12", "--seed", "4", "--plant", plant, "--controller", controller]
    assert main(["simulate", *args, "--out", str(tmp_path)]) == 0
    config = load_scenario()
    config.duration_s, config.random_seed = 12.0, 4
    config.plant = plant_from_shorthand(plant)
    config.controller = controller_from_shorthand(controller)
    write_recording(tmp_path / "whole.mcap", simulate(config).recording_channels())
    assert (tmp_path / "run.mcap").read_bytes() == (tmp_path / "whole.mcap").read_bytes()


def test_rendered_cameras_record_their_images_and_draw_their_first_and_last_frames(
    tmp_path, capsys
):
    out = tmp_path / "rendered"
    args = ["simulate", "--sensors", "rendered", "--duration", "2", "--image-rate", "3"]
    assert main([*args, "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["files"]["frames"] == str(out / "frames.png")
    assert (out / "frames.png").stat().st_size > 10_000
    # Both cameras' local filters took valid measurements from the rendered images.
    for camera in ("kinect_v1", "kinect_v2"):
        assert summary["estimation"][f"{camera}_valid_fraction"] > 0.9
    frames = read_camera_frames(out / "run.mcap")
    assert sorted(frames) == ["kinect_v1", "kinect_v2"]
    for camera_frames in frames.values():
        # 3 images a second at 15 frames a second: every 5th frame from the second on.
        times = [1 / 15 + k / 3 for k in range(6)]
        assert [round(f.time_s, 6) for f in camera_frames] == [round(t, 6) for t in times]
        assert all(f.valid and f.face_box is not None for f in camera_frames)
        assert all(len(f.eye_boxes) == 2 for f in camera_frames)


def test_a_rendered_run_is_the_same_recording_for_the_same_seed(tmp_path):
    recordings = []
    for attempt in range(2):
        out = tmp_path / f"run{attempt}"
        assert (
            main(["simulate", "--sensors", "rendered", "--duration", "1", "--out", str(out)]) == 0
        )
        recordings.append((out / "run.mcap").read_bytes())
    assert recordings[0] == recordings[1]
    assert b"foxglove.CompressedImage" in recordings[0]
    other = tmp_path / "other"
    args = ["simulate", "--sensors", "rendered", "--duration", "1", "--seed", "1"]
    assert main([*args, "--out", str(other)]) == 0
    assert (other / "run.mcap").read_bytes() != recordings[0]


def test_sensors_model_turns_a_rendered_config_back_to_the_formulas(tmp_path, capsys):
    config = tmp_path / "rendered.yaml"
    config.write_text("cameras:\n  kinect_v1:\n    rendering:\n      enabled: true\n")
    args = ["simulate", "--duration", "1", "--config", str(config), "--out", str(tmp_path)]
    assert main([*args, "--sensors", "model", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert "frames" not in summary["files"]
    assert main([*args, "--json", "--overwrite"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert list(read_camera_frames(tmp_path / "run.mcap")) == ["kinect_v1"]


def test_a_streaming_run_keeps_each_cameras_first_and_last_frame():
    frames = [face_frame(camera, t) for t in (0.1, 0.2, 0.3) for camera in ("a", "b")]
    frames.append(face_frame("c", 0.25))
    kept = first_and_last_frames(frames)
    assert [(f.camera, f.time_s) for f in kept] == [
        ("a", 0.1),
        ("b", 0.1),
        ("c", 0.25),
        ("a", 0.3),
        ("b", 0.3),
    ]


def _simulation_stopped_by(signum, out, stderr_path):
    """The exit code of a long `maskless simulate` sent ``signum`` once it has recorded a while.

    Its two workers are gone within 5 s, or the test fails.
    """
    psutil = pytest.importorskip("psutil")
    command = [sys.executable, "-m", "maskless.diagrams.cli", "simulate", "--duration", "3600"]
    with open(stderr_path, "w") as stderr:
        # Not a pipe: a worker that outlived the command would hold it open.
        process = subprocess.Popen(
            [*command, "--out", str(out)], stdout=subprocess.DEVNULL, stderr=stderr
        )
    partial = out / "run.partial.mcap"
    deadline = time.monotonic() + 60
    while not (partial.exists() and partial.stat().st_size > 100_000):
        assert time.monotonic() < deadline and process.poll() is None, "no recording came"
        time.sleep(0.05)
    workers = psutil.Process(process.pid).children(recursive=True)
    assert len(workers) == 2  # the recorder and the plotter
    process.send_signal(signum)
    code = process.wait(timeout=30)
    _, alive = psutil.wait_procs(workers, timeout=5)
    for orphan in alive:  # the test fails, and leaves nothing running behind it
        orphan.kill()
    assert not alive, f"workers {[p.pid for p in alive]} outlived the command"
    return code


def _messages_the_mcap_library_reads(path) -> int:
    with open(path, "rb") as f:
        reader = make_reader(f)
        assert reader.get_summary() is not None  # the footer and summary are there
        return sum(1 for _ in reader.iter_messages())


def test_a_killed_simulation_leaves_no_process_and_a_whole_partial_recording(tmp_path, capsys):
    out = tmp_path / "killed"
    code = _simulation_stopped_by(signal.SIGKILL, out, tmp_path / "stderr.txt")
    assert code == -signal.SIGKILL
    assert not (out / "run.mcap").exists()
    assert _messages_the_mcap_library_reads(out / "run.partial.mcap") > 1000
    with pytest.warns(TruncatedRecordingWarning, match="cut short"):
        assert read_recording(out / "run.partial.mcap").truncated
    # The killed run's lock is taken over; its recording is a run's file like any other.
    assert main(["simulate", "--duration", "1", "--out", str(out)]) == 2
    assert "run.partial.mcap: an earlier run's file is there" in capsys.readouterr().err
    assert main(["simulate", "--duration", "1", "--out", str(out), "--overwrite"]) == 0
    assert sorted(p.name for p in out.iterdir()) == ["run.mcap", "run.png"]


def test_a_terminated_simulation_says_so_in_one_line_and_finishes_its_recording(tmp_path):
    out, stderr = tmp_path / "terminated", tmp_path / "stderr.txt"
    code = _simulation_stopped_by(signal.SIGTERM, out, stderr)
    assert code == 128 + signal.SIGTERM
    partial = out / "run.partial.mcap"
    assert stderr.read_text().splitlines()[-1] == (
        f"maskless simulate: stopped by SIGTERM; what the run wrote is in {partial}"
    )
    assert "Traceback" not in stderr.read_text()
    assert sorted(p.name for p in out.iterdir()) == ["run.partial.mcap"]  # the lock released
    assert _messages_the_mcap_library_reads(partial) > 1000


def test_a_folder_holding_a_run_is_refused_before_anything_is_simulated(
    tmp_path, capsys, monkeypatch
):
    assert main(["simulate", "--duration", "1", "--out", str(tmp_path)]) == 0
    before = {p.name: p.read_bytes() for p in tmp_path.iterdir()}

    def never(*args, **kwargs):
        raise AssertionError("simulated into a refused folder")

    monkeypatch.setattr("maskless.diagrams.simulation.simulate", never)
    monkeypatch.setattr("maskless.diagrams.excitation_run.simulate_loop", never)
    assert main(["simulate", "--duration", "1", "--out", str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert error == (
        f"maskless simulate: error: {tmp_path / 'run.mcap'}: an earlier run's file is there; "
        "give --overwrite to replace that run\n"
    )
    assert main(["excite", "--duration", "2", "--out", str(tmp_path)]) == 2
    assert "give --overwrite" in capsys.readouterr().err
    assert {p.name: p.read_bytes() for p in tmp_path.iterdir()} == before
