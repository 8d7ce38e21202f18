"""The valve's static maps (the paper plant's dead zone and clip, an identified monotone map).

Each alike as a float and as a symbolic expression.
"""

import numpy as np
import pytest
from pydrake.symbolic import Variable

from maskless.errors import ModelError
from maskless.systems.plant.valve_map import ValveMap, effective_valve_current

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


# --- an identified map -------------------------------------------------------------------------

IDENTIFIED = ValveMap([0.060, 0.100, 0.120, 0.165], [0.0, 0.2, 0.2, 1.0])


@pytest.mark.parametrize(
    "current, expected",
    [(0.0, 0.0), (0.060, 0.0), (0.080, 0.1), (0.110, 0.2), (0.1425, 0.6), (0.165, 1.0), (0.3, 1.0)],
)
def test_an_identified_map_is_flat_outside_its_knots_and_linear_between(current, expected):
    assert IDENTIFIED.opening(current) == pytest.approx(expected)
    variable = Variable("i")
    symbolic = IDENTIFIED.opening(variable)
    assert symbolic.Evaluate({variable: current}) == pytest.approx(expected)


def test_the_inverse_gives_the_smallest_current_of_each_opening():
    assert IDENTIFIED.current_for_opening(0.2) == pytest.approx(0.100)  # not 0.120: flat run
    assert IDENTIFIED.current_for_opening(0.0) == pytest.approx(0.060)
    openings = np.linspace(0.0, 1.0, 41)
    np.testing.assert_allclose(
        IDENTIFIED.opening(IDENTIFIED.current_for_opening(openings)), openings
    )
    assert (IDENTIFIED.starting_current, IDENTIFIED.saturation_current) == (0.060, 0.165)


@pytest.mark.parametrize(
    "currents, openings, message",
    [
        ([0.06, 0.05], [0.0, 1.0], "increasing knots"),
        ([0.06, 0.1, 0.2], [0.0, 0.6, 0.5], "monotone"),
        ([0.06, 0.2], [0.1, 1.0], "from 0 to 1"),
        ([0.06, 0.2], [0.0, 0.9], "from 0 to 1"),
        ([0.06], [0.0], "one length >= 2"),
        ([0.06, np.nan], [0.0, 1.0], "finite"),
    ],
)
def test_a_bad_map_is_refused_naming_what_is_wrong(currents, openings, message):
    with pytest.raises(ModelError, match=message):
        ValveMap(currents, openings)
