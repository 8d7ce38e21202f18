"""The pressure pace check's tracker: its residual noise against closed forms, its limits.

Its behaviour inside the supervisor (a step's sum against the alarm, a step the commands explain,
a moving bladder) is tested tick by tick in test_safety_supervisor.py.
"""

import dataclasses
import math

import numpy as np
import pytest

from maskless.errors import ConfigError
from maskless.systems.control.pressure_pace_check import (
    PressurePaceConfig,
    lowest_drift_pa,
    residual_noise_gain,
    validate_pressure_pace,
)

CONFIG = PressurePaceConfig(
    level_gain=0.6,
    pace_gain=0.15,
    drift_pa=50.0,
    per_current_pa_per_a=5000.0,
    alarm_pa=100.0,
    still_pace_pa=10.0,
)


@pytest.mark.parametrize("alpha", [0.2, 0.6, 1.0, 1.5])
def test_without_a_pace_the_tracker_is_an_exponential_average(alpha):
    # Predicting with an exponential average of weight alpha, the residual is the new noise less
    # the average's error, whose variance is alpha / (2 - alpha): 2 / (2 - alpha) in all.
    assert residual_noise_gain(alpha, 0.0) == pytest.approx(math.sqrt(2 / (2 - alpha)), rel=1e-9)


@pytest.mark.parametrize("alpha, beta", [(0.6, 0.15), (0.3, 0.03), (1.2, 0.9)])
def test_the_residual_noise_gain_matches_white_noise_through_the_tracker(alpha, beta):
    rng = np.random.default_rng(3)
    noise = rng.standard_normal(400_000)
    level = pace = 0.0
    residuals = np.empty(noise.size)
    for k, reading in enumerate(noise):
        residuals[k] = reading - (level + pace)
        level, pace = level + pace + alpha * residuals[k], pace + beta * residuals[k]
    # 400,000 draws (the first thousand drop the start): the sample std within 1 %.
    assert np.std(residuals[1000:]) == pytest.approx(residual_noise_gain(alpha, beta), rel=0.01)


def test_the_lowest_drift_is_twice_the_residual_std_of_the_sensor_noise():
    assert lowest_drift_pa(CONFIG, 12.7) == pytest.approx(2 * 12.7 * residual_noise_gain(0.6, 0.15))


@pytest.mark.parametrize(
    "field, value",
    [
        ("level_gain", 0.0),
        ("level_gain", 2.0),
        ("pace_gain", 4 - 2 * 0.6),  # on the edge of the stability region
        ("pace_gain", 0.0),
        ("drift_pa", math.nan),
        ("per_current_pa_per_a", -1.0),
        ("alarm_pa", math.inf),
        ("still_pace_pa", 0.0),
    ],
)
def test_a_field_out_of_range_is_refused_by_name(field, value):
    with pytest.raises(ConfigError, match=f"safety.pressure_pace.{field} = "):
        validate_pressure_pace(
            dataclasses.replace(CONFIG, **{field: value}), "safety.pressure_pace"
        )


def test_the_shipped_check_is_valid():
    validate_pressure_pace(CONFIG, "safety.pressure_pace")
