"""maskless simulate: recording, plot and summary; the streamed recording is the one-shot one."""

import json

import pytest
from camera_frames import face_frame

from maskless.diagrams.cli import main
from maskless.diagrams.scenario import (
    controller_from_shorthand,
    load_scenario,
    plant_from_shorthand,
)
from maskless.diagrams.simulation import first_and_last_frames, simulate
from maskless.recording import read_camera_frames, read_recording, write_recording


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
    assert main([*args, "--json"]) == 0
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
