"""The Kinect models: noise as Nguyen et al. and Fankhauser et al. publish it, frames, checks."""

import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial
from system_harness import port_layout, simulate_with_constant_inputs

from maskless.errors import ConfigError
from maskless.systems.sensing.depth_sensor import (
    KinectV1Config,
    KinectV2Config,
    latency_frames,
    make_depth_sensor,
)

FRAMES = 20000
RATE_HZ = 15.0


SHARED = dict(
    mount_height_m=2.0,
    frame_rate_hz=RATE_HZ,
    latency_s=1 / RATE_HZ,
    dropout_probability=0.0,
    incidence_angle_rad=0.0,
)


def v1_config(**changes):
    return KinectV1Config(**{**SHARED, "min_range_m": 0.4, "max_range_m": 4.0, **changes})


def v2_config(**changes):
    v2_only = dict(
        min_range_m=0.5,
        max_range_m=4.5,
        offset_m=0.0,
        warmup_drift_m=0.0,
        warmup_time_constant_s=300.0,
        warmup_elapsed_s=0.0,
        resolution_m=0.001,
    )
    return KinectV2Config(**{**SHARED, **v2_only, **changes})


def frames_at(config, distance_m, count=FRAMES, seed=0):
    """``count`` frames of a head held ``distance_m`` below the camera: (distance, valid)."""
    sensor = make_depth_sensor("sensor", config)
    logs = simulate_with_constant_inputs(
        sensor,
        {"head_height_m": [config.mount_height_m - distance_m]},
        {"distance_m": 1 / config.frame_rate_hz, "valid": 1 / config.frame_rate_hz},
        duration_s=(count + 2) / config.frame_rate_hz,
        seed=seed,
    )
    skip = latency_frames(config) + 1  # frames before the first real one read invalid
    return logs["distance_m"][1][0, skip:], logs["valid"][1][0, skip:] > 0.5


@pytest.mark.parametrize("config", [v1_config(), v2_config()], ids=["kinect_v1", "kinect_v2"])
def test_ports(config):
    sensor = make_depth_sensor("kinect", config)
    assert sensor.get_name() == "kinect"
    assert port_layout(sensor) == ({"head_height_m": 1}, {"distance_m": 1, "valid": 1})


@pytest.mark.parametrize("distance_m", [0.7, 0.9])
def test_kinect_v1_noise_matches_nguyen_izadi_lovell(distance_m):
    distance, valid = frames_at(v1_config(), distance_m)
    assert valid.all()
    # Nguyen, Izadi, Lovell 2012 (normal incidence), plus the variance of rounding to disparity
    # levels 0.00307 z^2 apart (Sheppard's correction, step^2 / 12).
    sigma = 0.0012 + 0.0019 * (distance_m - 0.4) ** 2
    step = 0.00307 * distance_m**2
    expected = math.sqrt(sigma**2 + step**2 / 12)
    assert np.std(distance) == pytest.approx(expected, rel=0.03)
    assert np.mean(distance) == pytest.approx(
        distance_m, abs=3 * expected / math.sqrt(FRAMES) + 2e-4
    )


@pytest.mark.parametrize("distance_m", [0.7, 1.5])
def test_kinect_v2_noise_matches_fankhauser(distance_m):
    distance, valid = frames_at(v2_config(), distance_m)
    assert valid.all()
    # Fankhauser et al. 2015: sigma = 1.5 - 0.5 z + 0.3 z^2 mm, plus 1 mm rounding (step^2 / 12).
    sigma = (1.5 - 0.5 * distance_m + 0.3 * distance_m**2) / 1000
    expected = math.sqrt(sigma**2 + 0.001**2 / 12)
    assert np.std(distance) == pytest.approx(expected, rel=0.03)


def test_kinect_v1_quantisation_step_is_one_disparity_level():
    distance, _ = frames_at(v1_config(), 0.835, count=3000)
    levels = np.unique(distance)
    # z = 1 / (-0.00307 d + 3.3309): adjacent levels are ~0.00307 z^2 apart, ~2.1 mm at 0.835 m
    # (the authors' OpenNI log shows 2 mm steps there).
    near = levels[np.abs(levels - 0.835) < 0.004]
    np.testing.assert_allclose(np.diff(near), 0.00307 * 0.835**2, rtol=0.03)
    disparity = (1 / levels - 3.3309) / -0.00307
    np.testing.assert_allclose(disparity, np.round(disparity), atol=1e-6)


def test_kinect_v2_reports_whole_millimetres():
    distance, _ = frames_at(v2_config(), 0.7, count=2000)
    np.testing.assert_allclose(distance * 1000, np.round(distance * 1000), atol=1e-9)


@pytest.mark.parametrize(
    "config",
    [v1_config(dropout_probability=0.05), v2_config(dropout_probability=0.05)],
    ids=["v1", "v2"],
)
def test_dropout_rate_and_invalid_frames_read_zero(config):
    distance, valid = frames_at(config, 0.8)
    dropped = np.count_nonzero(~valid)
    # Binomial(20000, 0.05): mean 1000, std 30.8; allow 4 std.
    assert abs(dropped - 0.05 * FRAMES) < 4 * math.sqrt(FRAMES * 0.05 * 0.95)
    assert np.all(distance[~valid] == 0.0)
    assert np.all(distance[valid] > 0.0)


def test_out_of_range_frames_are_invalid():
    distance, valid = frames_at(v1_config(min_range_m=0.8), 0.6, count=100)
    assert not valid.any() and np.all(distance == 0.0)


def test_kinect_v2_offset_and_warmup_drift():
    config = v2_config(
        offset_m=0.01, warmup_drift_m=0.004, warmup_time_constant_s=20.0, warmup_elapsed_s=0.0
    )
    distance, _ = frames_at(config, 0.8, count=9000)
    times = (np.arange(distance.size) + latency_frames(config) + 1) / RATE_HZ
    late = times > 200  # drift has decayed to 4 mm * exp(-10)
    assert np.mean(distance[late]) == pytest.approx(0.81, abs=2e-4)
    # A frame logged at t was taken one frame earlier.
    early = (times > 5) & (times < 25)
    expected_early = 0.81 + np.mean(0.004 * np.exp(-(times[early] - 1 / RATE_HZ) / 20.0))
    assert np.mean(distance[early]) == pytest.approx(expected_early, abs=3e-4)


def test_latency_in_whole_frames():
    config = v2_config(latency_s=3 / RATE_HZ)  # three frames
    sensor = make_depth_sensor("sensor", config)
    step_time = 2.0
    trajectory = PiecewisePolynomial.ZeroOrderHold([0, step_time, 100], [[1.2, 1.1, 1.1]])
    builder = DiagramBuilder()
    builder.AddSystem(sensor)
    source = builder.AddSystem(TrajectorySource(trajectory))
    builder.Connect(source.get_output_port(), sensor.GetInputPort("head_height_m"))
    # Sample the output just after each frame.
    sink = builder.AddSystem(VectorLogSink(1, 1 / RATE_HZ))
    builder.Connect(sensor.GetOutputPort("distance_m"), sink.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(1))
    simulator.AdvanceTo(4.0)
    log = sink.FindLog(simulator.get_context())
    times, distance = log.sample_times(), log.data()[0]
    moved = times[np.flatnonzero(np.abs(distance - 0.9) < 0.02)[0]]
    # The frame taken 2 frames after the step shows it (the filter's tick adds the third), and a
    # log at a frame instant sees the frame before it: 3 frames in all after the step.
    assert moved == pytest.approx(step_time + 3 / RATE_HZ, abs=1e-9)


@pytest.mark.parametrize(
    "changes, field_name",
    [
        ({"frame_rate_hz": 0.0}, "frame_rate_hz"),
        ({"latency_s": 0.001}, "latency_s"),
        ({"dropout_probability": 1.0}, "dropout_probability"),
        ({"min_range_m": 5.0}, "min_range_m"),
        ({"incidence_angle_rad": 2.0}, "incidence_angle_rad"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(changes, field_name):
    with pytest.raises(ConfigError, match=f"kinect_v1.{field_name}"):
        make_depth_sensor("kinect_v1", v1_config(**changes))
