"""The shut-inlet check's limits and its hold in whole ticks.

Its behaviour inside the supervisor (a shut inlet with the pressure held, falling, low, or the
inlet opening again) is tested tick by tick in test_safety_supervisor.py, and on the pneumatic
plant with a stuck inlet by `maskless analyze faults` (README).
"""

import dataclasses
import math

import pytest

from maskless.errors import ConfigError
from maskless.systems.control.shut_inlet_check import (
    ShutInletConfig,
    hold_ticks,
    validate_shut_inlet,
)

CONFIG = ShutInletConfig(shut_current_a=0.0, hold_s=1.0, min_fall_pa=100.0, min_pressure_pa=1000.0)


@pytest.mark.parametrize(
    "hold_s, period_s, ticks",
    [(1.0, 1 / 15, 15), (1.0, 0.1, 10), (0.35, 0.1, 4), (0.25, 0.1, 3), (0.05, 0.1, 3)],
)
def test_the_hold_is_whole_ticks_rounded_up_and_at_least_three(hold_s, period_s, ticks):
    # Three: a tick to note the level, two for a command to reach the reading.
    assert hold_ticks(dataclasses.replace(CONFIG, hold_s=hold_s), period_s) == ticks


@pytest.mark.parametrize(
    "field, value",
    [
        ("shut_current_a", -0.001),
        ("hold_s", 0.0),
        ("hold_s", math.inf),
        ("min_fall_pa", 0.0),
        ("min_fall_pa", math.nan),
        ("min_pressure_pa", -1.0),
    ],
)
def test_a_field_out_of_range_is_refused_by_name(field, value):
    with pytest.raises(ConfigError, match=f"safety.shut_inlet.{field} = "):
        validate_shut_inlet(dataclasses.replace(CONFIG, **{field: value}), "safety.shut_inlet")


def test_the_shipped_values_pass():
    validate_shut_inlet(CONFIG, "safety.shut_inlet")
