"""The Kinect models: noise as Nguyen et al. and Fankhauser et al. publish it, frames, checks."""

import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial
from system_harness import port_layout, simulate_with_constant_inputs

from maskless.errors import ConfigError
from maskless.systems.named_symbolic_system import add_symbolic_system, as_diagram
from maskless.systems.sensing.depth_sensor import (
    KinectV1Config,
    KinectV2Config,
    add_depth_sensor,
    add_depth_sensors,
    depth_sensor_system,
    latency_frames,
    make_depth_sensor,
    reported_distance_m,
)

FRAMES = 20000
RATE_HZ = 15.0


SHARED = dict(
    mount_height_m=2.0,
    frame_rate_hz=RATE_HZ,
    latency_s=1 / RATE_HZ,
    dropout_probability=0.0,
    incidence_angle_rad=0.0,
    warmup_drift_m=0.0,
    warmup_time_constant_s=300.0,
    warmup_elapsed_s=0.0,
)


def v1_config(**changes):
    return KinectV1Config(**{**SHARED, "min_range_m": 0.4, "max_range_m": 4.0, **changes})


def v2_config(**changes):
    v2_only = dict(min_range_m=0.5, max_range_m=4.5, resolution_m=0.001)
    return KinectV2Config(**{**SHARED, **v2_only, **changes})


CONFIGS = {"kinect_v1": v1_config, "kinect_v2": v2_config}

# A warm-up drift large against the quantisation steps (~2 mm, 1 mm), decaying within the run.
WARMUP = dict(warmup_drift_m=0.01, warmup_time_constant_s=20.0, warmup_elapsed_s=5.0)


def warmup_drift_m(time_s, warmup_drift_m, warmup_time_constant_s, warmup_elapsed_s):
    """The drift's definition: drift(t) = drift0 exp(-(t + elapsed) / time constant)."""
    return warmup_drift_m * np.exp(-(time_s + warmup_elapsed_s) / warmup_time_constant_s)


def quantised_m(name, distance_m):
    """The nearest level a noise-free camera reports: an 11-bit disparity (v1) or 1 mm (v2)."""
    if name == "kinect_v1":
        disparity = np.round((1 / distance_m - 3.3309) / -0.00307)
        return 1 / (-0.00307 * disparity + 3.3309)
    return 0.001 * np.round(distance_m / 0.001)


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


@pytest.mark.parametrize("name", CONFIGS)
def test_warmup_drift_is_added_before_quantisation(name):
    config = CONFIGS[name](**WARMUP)
    times = np.array([0.0, 7.0, 20.0, 45.0])
    reported = [reported_distance_m(config, 0.8, 0.0, t) for t in times]
    expected = quantised_m(name, 0.8 + warmup_drift_m(times, **WARMUP))
    np.testing.assert_allclose(reported, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("name", CONFIGS)
def test_noise_free_frames_follow_the_decaying_warmup_drift(name):
    config = CONFIGS[name](**WARMUP)
    period_s = 1 / config.frame_rate_hz
    # The camera's frame dynamics with a zero noise draw: a noise-free camera of this model.
    camera = as_diagram(
        "camera", lambda b: add_symbolic_system(b, "camera", depth_sensor_system(config, period_s))
    )
    logs = simulate_with_constant_inputs(
        camera,
        {"head_height_m": [config.mount_height_m - 0.8], "standard_normal": [0.0, 0.0]},
        {"distance_m": period_s, "valid": period_s},
        duration_s=60.0,
    )
    times, distance = logs["distance_m"][0], logs["distance_m"][1][0]
    valid = logs["valid"][1][0] > 0.5
    assert np.count_nonzero(valid) > 850
    # A frame logged at t was taken one frame earlier.
    expected = quantised_m(name, 0.8 + warmup_drift_m(times[valid] - period_s, **WARMUP))
    np.testing.assert_allclose(distance[valid], expected, rtol=0, atol=1e-12)
    # The drift decays: early frames read far, late ones the true distance.
    assert distance[valid][0] - 0.8 > 0.006
    assert distance[-1] == pytest.approx(quantised_m(name, 0.8), abs=1e-12)


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


@pytest.mark.parametrize("name", CONFIGS)
@pytest.mark.parametrize(
    "changes, field_name",
    [
        ({"frame_rate_hz": 0.0}, "frame_rate_hz"),
        ({"latency_s": 0.001}, "latency_s"),
        ({"dropout_probability": 1.0}, "dropout_probability"),
        ({"min_range_m": 5.0}, "min_range_m"),
        ({"incidence_angle_rad": 2.0}, "incidence_angle_rad"),
        ({"warmup_drift_m": math.inf}, "warmup_drift_m"),
        ({"warmup_drift_m": math.nan}, "warmup_drift_m"),
        ({"warmup_time_constant_s": 0.0}, "warmup_time_constant_s"),
        ({"warmup_time_constant_s": math.inf}, "warmup_time_constant_s"),
        ({"warmup_elapsed_s": -1.0}, "warmup_elapsed_s"),
        ({"warmup_elapsed_s": math.nan}, "warmup_elapsed_s"),
    ],
)
def test_bad_parameters_are_refused_naming_the_field(name, changes, field_name):
    with pytest.raises(ConfigError, match=rf"{name}\.{field_name} ="):
        make_depth_sensor(name, CONFIGS[name](**changes))


def camera_frames(banked: bool, configs: dict, seed: int = 4) -> dict[str, np.ndarray]:
    """200 frames of each camera watching a fixed head, the cameras banked or one at a time."""
    builder = DiagramBuilder()
    head = builder.AddSystem(ConstantVectorSource([1.2]))
    if banked:
        ports = add_depth_sensors(builder, configs)
    else:
        ports = {name: add_depth_sensor(builder, name, config) for name, config in configs.items()}
    for name, sensor in ports.items():
        builder.Connect(head.get_output_port(), sensor.inputs["head_height_m"])
        builder.ExportOutput(sensor.outputs["distance_m"], name)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    frames = {name: [] for name in configs}
    for frame in range(200):
        simulator.AdvanceTo(frame / RATE_HZ)
        for name in configs:
            frames[name].append(diagram.GetOutputPort(name).Eval(simulator.get_context())[0])
    return {name: np.array(values) for name, values in frames.items()}


def test_banked_cameras_draw_and_report_what_cameras_added_alone_do():
    # The warm-up drift puts time in the second camera's expressions: the bank's shared time.
    configs = {
        "kinect_v1": v1_config(),
        "kinect_v2": v2_config(dropout_probability=0.1, **WARMUP),
    }
    alone, banked = camera_frames(False, configs), camera_frames(True, configs)
    for name in configs:
        np.testing.assert_array_equal(banked[name], alone[name])
        assert np.ptp(banked[name]) > 0  # noisy frames, not a constant that would match anyway
    # Cameras of other frame rates are banks of their own.
    builder = DiagramBuilder()
    add_depth_sensors(
        builder, {"a": v1_config(), "b": v2_config(), "c": v1_config(frame_rate_hz=30)}
    )
    names = {system.get_name() for system in builder.GetSystems()}
    assert {"a+b", "c"} <= names
