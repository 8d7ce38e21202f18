"""The valve's static map (dead zone, saturation), alike as a float and as a symbolic expression."""

import pytest
from pydrake.symbolic import Variable

from maskless.systems.plant.valve_map import effective_valve_current

START, SATURATION = 0.060, 0.165


@pytest.mark.parametrize(
    "current, expected",
    [
        (-0.01, 0.0),
        (0.0, 0.0),
        (0.0599, 0.0),
        (0.060, 0.060),
        (0.1, 0.1),
        (0.165, 0.165),
        (0.2, 0.165),
    ],
)
def test_dead_zone_and_saturation(current, expected):
    assert effective_valve_current(current, START, SATURATION) == pytest.approx(expected)


@pytest.mark.parametrize("current", [-0.01, 0.03, 0.0601, 0.12, 0.3])
def test_symbolic_form_evaluates_like_the_float_form(current):
    variable = Variable("i")
    expression = effective_valve_current(variable, START, SATURATION)
    value = expression.Evaluate({variable: current})
    assert value == pytest.approx(effective_valve_current(current, START, SATURATION))
