"""Camera error beyond the per-pixel formulas: offset, white noise, Gauss-Markov, paper preset."""

import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink

from maskless.diagrams.scenario import load_scenario
from maskless.errors import ConfigError
from maskless.systems.config_loading import asset_path
from maskless.systems.named_symbolic_system import PortMap
from maskless.systems.sensing.camera_error import (
    CameraErrorConfig,
    add_camera_error,
    validate_camera_error,
)
from maskless.systems.sensing.depth_sensor import add_depth_sensor

PERIOD_S = 1 / 15


def error(**fields) -> CameraErrorConfig:
    values = dict(
        enabled=True,
        offset_m=0.0,
        white_noise_std_m=0.0,
        correlated_std_m=0.0,
        correlation_time_s=0.5,
    )
    return CameraErrorConfig(**{**values, **fields})


def run_error(config, distance_m, valid, frames, seed=0):
    """The error system alone on a constant measurement: its distance output, one per frame."""
    builder = DiagramBuilder()
    camera = PortMap(
        outputs={
            "distance_m": builder.AddSystem(ConstantVectorSource([distance_m])).get_output_port(),
            "valid": builder.AddSystem(ConstantVectorSource([valid])).get_output_port(),
        }
    )
    ports = add_camera_error(builder, "kinect_v1", config, camera, PERIOD_S)
    log = builder.AddSystem(VectorLogSink(1, PERIOD_S))
    builder.Connect(ports.outputs["distance_m"], log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    simulator.AdvanceTo(frames * PERIOD_S)
    return log.FindLog(simulator.get_context()).data()[0]


def test_an_offset_is_added_to_every_valid_frame_and_an_invalid_frame_stays_zero():
    assert np.all(run_error(error(offset_m=0.002), 0.8, 1.0, 20) == pytest.approx(0.802))
    assert np.all(run_error(error(offset_m=0.002, white_noise_std_m=0.01), 0.0, 0.0, 20) == 0.0)


def test_white_noise_has_its_std_and_no_memory():
    values = run_error(error(white_noise_std_m=0.003), 0.8, 1.0, 20000)
    assert values.std() == pytest.approx(0.003, rel=0.03)
    centred = values - values.mean()
    lag_one = np.dot(centred[1:], centred[:-1]) / np.dot(centred, centred)
    assert abs(lag_one) < 4 / math.sqrt(values.size)


def test_gauss_markov_error_has_its_variance_and_autocorrelation():
    tau, std = 0.5, 0.002
    values = run_error(error(correlated_std_m=std, correlation_time_s=tau), 0.8, 1.0, 60000)
    values = values[int(10 * tau / PERIOD_S) :] - 0.8  # past the start from zero
    assert values.std() == pytest.approx(std, rel=0.05)
    centred = values - values.mean()
    for lag in (1, 4, 8):
        measured = np.dot(centred[lag:], centred[:-lag]) / np.dot(centred, centred)
        assert measured == pytest.approx(math.exp(-lag * PERIOD_S / tau), abs=0.03)


def test_disabled_error_adds_nothing():
    camera = PortMap(outputs={})
    assert add_camera_error(DiagramBuilder(), "k", CameraErrorConfig(), camera, PERIOD_S) is camera


def test_the_paper_preset_gives_each_camera_the_papers_measured_variance():
    scenario = load_scenario(asset_path("presets/paper_camera_noise.yaml"))
    height_m = scenario.pneumatic.rest_head_height_m + scenario.start_lift_m
    expected_mm2 = {
        "kinect_v1": scenario.paper.measured_noise_kinect_v1_mm2,
        "kinect_v2": scenario.paper.measured_noise_kinect_v2_mm2,
    }
    for name, camera in scenario.cameras.items():
        camera.dropout_probability = 0.0
        builder = DiagramBuilder()
        sensor = add_depth_sensor(builder, name, camera)
        head = builder.AddSystem(ConstantVectorSource([height_m]))
        builder.Connect(head.get_output_port(), sensor.inputs["head_height_m"])
        ports = add_camera_error(builder, name, camera.error, sensor, 1 / camera.frame_rate_hz)
        log = builder.AddSystem(VectorLogSink(1, 1 / camera.frame_rate_hz))
        builder.Connect(ports.outputs["distance_m"], log.get_input_port())
        diagram = builder.Build()
        simulator = Simulator(diagram)
        diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(1))
        simulator.AdvanceTo(1500.0)
        values = log.FindLog(simulator.get_context()).data()[0][2:]  # past the first frame
        assert values.var() * 1e6 == pytest.approx(expected_mm2[name], rel=0.05)


@pytest.mark.parametrize(
    "fields, name",
    [
        (dict(offset_m=math.nan), "offset_m"),
        (dict(white_noise_std_m=-0.001), "white_noise_std_m"),
        (dict(correlated_std_m=math.inf), "correlated_std_m"),
        (dict(correlation_time_s=0.0), "correlation_time_s"),
    ],
)
def test_a_value_out_of_range_is_refused_naming_the_field(fields, name):
    with pytest.raises(ConfigError, match=rf"cameras\.kinect_v1\.error\.{name} ="):
        validate_camera_error("cameras.kinect_v1", error(**fields))
