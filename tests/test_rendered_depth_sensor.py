"""The rendered camera: Drake's RgbdSensor, face detection, a measurement on the model's ports."""

import copy
import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink
from rendered_scene import build_rendered_scene, head_travel_m, shipped_cameras

from maskless.systems.sensing.camera_scene import add_camera_scene
from maskless.systems.sensing.depth_sensor import latency_frames
from maskless.systems.sensing.face_detection import FaceFinder
from maskless.systems.sensing.rendered_depth_sensor import (
    add_rendered_depth_sensor,
    camera_info,
    measure_frame,
)


def quantisation_step_m(name, distance_m):
    """Kinect v1: one 11-bit disparity level, 0.00307 z^2 (shared/DESIGN.md); v2: 1 mm."""
    return 0.00307 * distance_m**2 if name == "kinect_v1" else 0.001


def test_intrinsics_give_the_configured_fields_of_view():
    for camera in shipped_cameras().values():
        for scale in (1.0, camera.rendering.color_scale):
            info = camera_info(camera, scale)
            assert 2 * math.degrees(math.atan(info.width() / 2 / info.focal_x())) == pytest.approx(
                camera.rendering.horizontal_fov_deg
            )
            assert 2 * math.degrees(math.atan(info.height() / 2 / info.focal_y())) == pytest.approx(
                camera.rendering.vertical_fov_deg
            )
            assert info.width() == round(camera.rendering.image_width_px * scale)


@pytest.fixture(scope="module")
def scene():
    return build_rendered_scene(shipped_cameras())


@pytest.mark.parametrize("height_m", head_travel_m(), ids=["lowest", "middle", "highest"])
@pytest.mark.parametrize("name", ["kinect_v1", "kinect_v2"])
def test_noise_free_region_depth_is_the_true_face_distance_within_one_step(scene, name, height_m):
    config, _ = scene.cameras[name]
    rgba, depth = scene.render(name, height_m)
    found = measure_frame(FaceFinder(), config, rgba, depth, None, None, 0.0)
    assert found.valid, found.reason
    assert len(found.eye_boxes) == 2
    true_distance_m = config.mount_height_m - height_m
    step_m = quantisation_step_m(name, true_distance_m)
    assert abs(found.distance_m - true_distance_m) <= step_m


def test_a_dropped_frame_is_no_measurement_and_searches_nothing(scene):
    config = copy.deepcopy(scene.cameras["kinect_v2"][0])
    config.dropout_probability = 0.999999
    rgba, depth = scene.render("kinect_v2", 0.21)
    dropped = measure_frame(FaceFinder(), config, rgba, depth, None, np.random.default_rng(0), 0.0)
    assert not dropped.valid and dropped.reason == "frame dropped"
    assert dropped.face_box is None and np.isnan(dropped.distance_m)


def _run_sensor(cameras, height_m, duration_s, seed=0, frames=None, every=1):
    builder = DiagramBuilder()
    head = builder.AddSystem(ConstantVectorSource([height_m]))
    scene = add_camera_scene(builder, head.get_output_port())
    logs = {}
    for name, config in cameras.items():
        sink = None if frames is None else (lambda *args: frames.append(args))
        ports = add_rendered_depth_sensor(builder, name, config, scene, sink, every)
        for port in ("distance_m", "valid"):
            log = builder.AddSystem(VectorLogSink(1, 1 / config.frame_rate_hz))
            builder.Connect(ports.outputs[port], log.get_input_port())
            logs[name, port] = log
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(seed))
    simulator.AdvanceTo(duration_s)
    return {key: log.FindLog(context).data()[0] for key, log in logs.items()}


@pytest.mark.parametrize("height_m", head_travel_m(), ids=["lowest", "middle", "highest"])
def test_every_frame_finds_the_face_and_measures_it_on_the_model_ports(height_m):
    cameras = shipped_cameras(invalid_pixel_probability=0.01)
    for camera in cameras.values():
        camera.dropout_probability = 0.0
    logs = _run_sensor(cameras, height_m, 1.0)
    for name, camera in cameras.items():
        valid, distance = logs[name, "valid"], logs[name, "distance_m"]
        # The first sample is before any frame arrived (one frame of latency).
        assert valid[0] == 0 and distance[0] == 0
        assert np.all(valid[1:] == 1)
        true_distance_m = camera.mount_height_m - height_m
        error = distance[1:] - true_distance_m
        # Per-pixel noise averages over the region: well within one quantisation step.
        assert np.all(np.abs(error) < quantisation_step_m(name, true_distance_m))


def test_a_face_out_of_view_gives_valid_false_and_no_number():
    cameras = shipped_cameras()
    for camera in cameras.values():
        camera.rendering.position_m = [0.9, 0.0]  # the face is far outside the view
    logs = _run_sensor(cameras, 0.21, 0.5)
    for name in cameras:
        assert np.all(logs[name, "valid"] == 0)
        assert np.all(logs[name, "distance_m"] == 0)


def test_the_same_seed_gives_the_same_measurements_and_another_seed_others():
    cameras = shipped_cameras()
    first = _run_sensor(cameras, 0.21, 0.6, seed=5)
    again = _run_sensor(cameras, 0.21, 0.6, seed=5)
    other = _run_sensor(cameras, 0.21, 0.6, seed=6)
    for key in first:
        np.testing.assert_array_equal(first[key], again[key])
    assert not np.array_equal(first["kinect_v1", "distance_m"], other["kinect_v1", "distance_m"])


def test_every_nth_frame_is_recorded_with_its_image_and_boxes():
    frames = []
    cameras = shipped_cameras()
    _run_sensor(cameras, 0.21, 1.0, frames=frames, every=4)
    for name, camera in cameras.items():
        recorded = [f for f in frames if f[0] == name]
        times = [f[1] for f in recorded]
        # Every 4th frame from the second on (frames 1, 5, 9, 13 of 15 per second).
        np.testing.assert_allclose(times, np.arange(1, 15, 4) / camera.frame_rate_hz)
        _, _, rgb, measurement = recorded[-1]
        assert rgb.shape == (
            round(camera.rendering.image_height_px * camera.rendering.color_scale),
            round(camera.rendering.image_width_px * camera.rendering.color_scale),
            3,
        )
        assert measurement.valid and measurement.face_box is not None


def test_a_longer_latency_holds_each_measurement_more_frames_as_the_model_sensor_does():
    cameras = shipped_cameras()
    camera = cameras["kinect_v2"]
    camera.dropout_probability = 0.0
    camera.latency_s = 3 / camera.frame_rate_hz
    logs = _run_sensor({"kinect_v2": camera}, 0.21, 0.6)
    # latency_frames = 3: the frame taken at t = 0 is on the port from 3 frames on.
    assert latency_frames(camera) == 3
    np.testing.assert_array_equal(logs["kinect_v2", "valid"][:4], [0, 0, 0, 1])


def test_a_recorded_frame_is_the_measurement_its_filter_receives():
    frames = []
    cameras = shipped_cameras()
    logs = _run_sensor(cameras, 0.21, 1.0, frames=frames, every=3)
    for name, camera, time_s, _, measurement in ((f[0], cameras[f[0]], *f[1:]) for f in frames):
        # The port shows a frame from the next tick on (one frame of latency).
        index = round(time_s * camera.frame_rate_hz) + 1
        assert logs[name, "valid"][index] == measurement.valid == 1
        assert logs[name, "distance_m"][index] == measurement.distance_m
