"""The bladder's pressure sensor: rounding, range, noise, seeding, the scenario's checks of it."""

import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink

from maskless.diagrams.scenario import load_scenario, validate_scenario
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from maskless.systems.config_loading import asset_path
from maskless.systems.control.pressure_pace_check import lowest_drift_pa
from maskless.systems.sensing.pressure_sensor import (
    PressureSensorConfig,
    add_pressure_sensor,
    reading_noise_std_pa,
    sensor_reading,
)

PERIOD_S = 1 / 15


def sensor(**fields) -> PressureSensorConfig:
    values = dict(resolution_pa=12.2, noise_std_pa=0.0, lowest_pa=-25000.0, highest_pa=25000.0)
    return PressureSensorConfig(**{**values, **fields})


def read(config, pressure_pa, ticks=1, seed=0):
    """The sensor alone on a constant pressure: its reading at each of ``ticks`` ticks."""
    builder = DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource([pressure_pa]))
    reading = add_pressure_sensor(builder, "sensor", config, source.get_output_port(), PERIOD_S)
    log = builder.AddSystem(VectorLogSink(1, PERIOD_S))
    builder.Connect(reading, log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    simulator.AdvanceTo((ticks - 0.5) * PERIOD_S)
    return log.FindLog(simulator.get_context()).data()[0]


@pytest.mark.parametrize("pressure_pa", [0.0, 6.0, 6.2, -6.2, 100.0, 2979.3, -18000.0, 14999.0])
def test_a_reading_is_the_nearest_count_within_the_range(pressure_pa):
    # Half a count rounds up, as floor(x + 1/2) does.
    expected = 12.2 * math.floor(pressure_pa / 12.2 + 0.5)
    assert read(sensor(), pressure_pa)[0] == pytest.approx(expected, abs=1e-9)
    assert abs(read(sensor(), pressure_pa)[0] - pressure_pa) <= 6.1 + 1e-9


def test_beyond_its_range_it_reads_its_range_and_unrounded_it_reads_the_pressure():
    assert read(sensor(), 40000.0)[0] == 25000.0
    assert read(sensor(), -90000.0)[0] == -25000.0
    assert read(sensor(resolution_pa=0.0), 1234.5678)[0] == 1234.5678


def test_its_noise_has_the_stated_std_is_seeded_and_rounded():
    readings = read(sensor(resolution_pa=0.0, noise_std_pa=10.0), 500.0, ticks=4000)
    # The sample std of 4000 normal draws lies within 4 % of sigma about 99.99 % of the time.
    assert np.std(readings) == pytest.approx(10.0, rel=0.04)
    assert abs(np.mean(readings) - 500.0) < 4 * 10.0 / math.sqrt(4000)
    again = read(sensor(resolution_pa=0.0, noise_std_pa=10.0), 500.0, ticks=4000)
    np.testing.assert_array_equal(readings, again)
    rounded = read(sensor(noise_std_pa=10.0), 500.0, ticks=50)
    np.testing.assert_allclose(rounded / 12.2, np.round(rounded / 12.2), atol=1e-9)


def test_the_reading_noise_counts_the_rounding_as_uniform_over_one_count():
    assert reading_noise_std_pa(sensor(noise_std_pa=0.0)) == pytest.approx(12.2 / math.sqrt(12))
    assert reading_noise_std_pa(sensor(resolution_pa=0.0, noise_std_pa=3.0)) == pytest.approx(3.0)
    # A smooth pressure's rounding errors, over many counts, have that std.
    ticks = np.arange(20000)
    smooth = 12000.0 * np.sin(2 * np.pi * ticks / 3001.0) + 0.37 * ticks - 3000.0  # within range
    readings = np.array([sensor_reading(float(p), 0.0, sensor()) for p in smooth])
    errors = readings - smooth
    assert np.max(np.abs(errors)) <= 12.2 / 2 + 1e-9
    assert np.std(errors) == pytest.approx(12.2 / math.sqrt(12), rel=0.03)


@pytest.mark.parametrize(
    "field, value, message",
    [
        ("resolution_pa", -1.0, "pressure_sensor.resolution_pa = -1.0: expected a finite count"),
        ("noise_std_pa", math.inf, "pressure_sensor.noise_std_pa = inf: expected a finite std"),
        ("highest_pa", -30000.0, "pressure_sensor.highest_pa = -30000.0: expected a finite"),
    ],
)
def test_a_sensor_out_of_range_is_refused_naming_the_field(field, value, message):
    config = load_scenario()
    setattr(config.pressure_sensor, field, value)
    with pytest.raises(ConfigError, match=message):
        validate_scenario(config)


def test_a_pace_check_the_sensor_alone_would_fill_is_refused():
    config = load_scenario()
    # 2 x 1.3031 x sqrt(20^2 + 12.2^2 / 12) = 52.93 Pa, above the shipped 50 Pa.
    config.pressure_sensor.noise_std_pa = 20.0
    with pytest.raises(
        ConfigError, match=r"safety.pressure_pace.drift_pa = 50.0: expected at least 52.93 Pa"
    ):
        validate_scenario(config)


def test_a_noisy_sensor_leaves_every_other_draw_as_it_was():
    # Its RandomSource comes after every other: the cameras' measurements are the same bits.
    runs = []
    for noise_std_pa in (0.0, 1.0):
        config = load_scenario()
        config.duration_s, config.random_seed = 3.0, 7
        config.pressure_sensor.noise_std_pa = noise_std_pa
        runs.append(simulate(config).signals)
    cameras = [name for name in runs[0] if "kinect" in name]
    assert cameras
    for name in cameras:
        np.testing.assert_array_equal(runs[0][name].values, runs[1][name].values)


def test_the_noisy_preset_clears_its_own_sensor():
    config = load_scenario(asset_path("presets/noisy_pressure_sensor.yaml"))
    validate_scenario(config)
    assert config.pressure_sensor.noise_std_pa == 12.2
    pace = config.safety.pressure_pace
    noise = reading_noise_std_pa(config.pressure_sensor)
    assert lowest_drift_pa(pace, noise) < pace.drift_pa
