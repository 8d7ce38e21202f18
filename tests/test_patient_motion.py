"""The patient's motion against its definition: drift rate, shift timing and size, breathing."""

import math

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink

from maskless.errors import ConfigError
from maskless.systems.plant.patient_motion import (
    PatientMotionConfig,
    add_patient_motion,
    validate_patient_motion,
)

LIFT_M = 0.21


def motion(**fields) -> PatientMotionConfig:
    values = dict(
        enabled=True,
        tick_s=0.1,
        drift_rate_m_per_s=0.0,
        shift_rate_per_s=0.0,
        shift_std_m=0.0,
        shift_time_constant_s=0.2,
        breathing_amplitude_m=0.0,
        breathing_frequency_hz=0.25,
    )
    return PatientMotionConfig(**{**values, **fields})


def simulate_motion(config, duration_s, seed=0, period_s=None):
    """(times, head height - lift) logged every ``period_s`` (the tick by default)."""
    builder = DiagramBuilder()
    lift = builder.AddSystem(ConstantVectorSource([LIFT_M]))
    head = add_patient_motion(builder, config, lift.get_output_port(), "patient_motion")
    log = builder.AddSystem(VectorLogSink(1, period_s or config.tick_s))
    builder.Connect(head, log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    simulator.AdvanceTo(duration_s)
    data = log.FindLog(simulator.get_context())
    return data.sample_times(), data.data()[0] - LIFT_M


def test_drift_is_the_configured_rate():
    times, offset = simulate_motion(motion(drift_rate_m_per_s=3.3e-6), 300.0)
    assert np.polyfit(times, offset, 1)[0] == pytest.approx(3.3e-6, rel=1e-9)


def test_breathing_has_the_configured_amplitude_and_frequency_and_a_drawn_phase():
    config = motion(breathing_amplitude_m=0.0005, breathing_frequency_hz=0.25)
    times, offset = simulate_motion(config, 200.0, period_s=0.01)
    assert np.abs(offset).max() == pytest.approx(0.0005, rel=1e-3)
    spectrum = np.abs(np.fft.rfft(offset))
    frequencies = np.fft.rfftfreq(offset.size, 0.01)
    assert frequencies[np.argmax(spectrum)] == pytest.approx(0.25, abs=0.01)
    _, other_seed = simulate_motion(config, 200.0, seed=1, period_s=0.01)
    assert not np.allclose(offset, other_seed)


def _targets(level, tick_s, time_constant_s):
    """The shift targets behind a level sequence L+ = L + b (T+ - L), recovered exactly."""
    blend = 1 - math.exp(-tick_s / time_constant_s)
    return level[:-1] + np.diff(level) / blend


def test_shifts_arrive_as_a_poisson_process_with_the_configured_size_and_speed():
    rate, std, duration = 0.5, 0.002, 400.0
    config = motion(shift_rate_per_s=rate, shift_std_m=std)
    _, level = simulate_motion(config, duration)
    targets = _targets(level, config.tick_s, config.shift_time_constant_s)
    sizes = np.diff(targets)[np.abs(np.diff(targets)) > 1e-12]
    expected = rate * duration
    assert abs(sizes.size - expected) < 4 * math.sqrt(expected)  # Poisson count
    assert np.std(sizes) == pytest.approx(std, rel=0.15)


def test_the_gaps_between_shifts_are_exponential_with_mean_one_over_the_rate():
    rate = 0.5
    config = motion(shift_rate_per_s=rate, shift_std_m=0.002)
    _, level = simulate_motion(config, 2000.0, seed=5)
    targets = _targets(level, config.tick_s, config.shift_time_constant_s)
    gaps = np.diff(np.flatnonzero(np.abs(np.diff(targets)) > 1e-12)) * config.tick_s
    # One draw per tick: the gaps are geometric, mean tick / p and std tick sqrt(1 - p) / p, which
    # tend to the exponential's 1 / rate as the ticks shrink.
    p = rate * config.tick_s
    mean, std = config.tick_s / p, config.tick_s * math.sqrt(1 - p) / p
    assert gaps.mean() == pytest.approx(mean, rel=4 / math.sqrt(gaps.size))
    assert gaps.std() == pytest.approx(std, rel=0.1)
    assert mean == pytest.approx(1 / rate)


def test_a_shift_is_made_within_a_second():
    # Rare shifts: how much of each the head has made 0.6 s after it starts, against where it
    # rests 5 s later (read from the motion itself).
    config = motion(shift_rate_per_s=0.02, shift_std_m=0.002)
    _, level = simulate_motion(config, 600.0, seed=2)
    targets = _targets(level, config.tick_s, config.shift_time_constant_s)
    starts = np.flatnonzero(np.abs(np.diff(targets)) > 1e-9) + 1  # the tick whose update moved
    made = []
    for start, following in zip(starts, [*starts[1:], level.size], strict=True):
        if following - start > 50 and start + 50 < level.size:
            before, rest = level[start], level[start + 50]
            made.append((level[start + 6] - before) / (rest - before))
    assert len(made) >= 5
    assert min(made) > 0.95


def test_the_same_seed_gives_the_same_motion():
    config = motion(shift_rate_per_s=0.5, shift_std_m=0.002, breathing_amplitude_m=0.0005)
    first = simulate_motion(config, 30.0, seed=3)[1]
    np.testing.assert_array_equal(first, simulate_motion(config, 30.0, seed=3)[1])
    assert not np.array_equal(first, simulate_motion(config, 30.0, seed=4)[1])


def test_no_motion_adds_nothing():
    builder = DiagramBuilder()
    lift = builder.AddSystem(ConstantVectorSource([LIFT_M]))
    port = lift.get_output_port()
    assert add_patient_motion(builder, PatientMotionConfig(), port, "patient_motion") is port


@pytest.mark.parametrize(
    "fields, name",
    [
        (dict(tick_s=0.0), "tick_s"),
        (dict(shift_rate_per_s=1.0), "shift_rate_per_s"),
        (dict(tick_s=math.inf), "tick_s"),
        (dict(breathing_amplitude_m=math.inf), "breathing_amplitude_m"),
        (dict(shift_std_m=-1.0), "shift_std_m"),
        (dict(shift_time_constant_s=0.0), "shift_time_constant_s"),
        (dict(breathing_amplitude_m=-0.001), "breathing_amplitude_m"),
        (dict(drift_rate_m_per_s=math.inf), "drift_rate_m_per_s"),
    ],
)
def test_a_value_out_of_range_is_refused_naming_the_field(fields, name):
    with pytest.raises(ConfigError, match=rf"patient_motion\.{name} ="):
        validate_patient_motion(motion(**fields))
