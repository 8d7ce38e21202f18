"""The step reference: levels at the right times, rewritable in a Context, malformed refused."""

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.trajectories import PiecewisePolynomial

from maskless.errors import ConfigError
from maskless.systems.control.step_reference import (
    add_step_reference,
    set_step_levels,
    step_levels,
)

TIMES_S = [5.0, 35.0]
LEVELS_M = [0.2077, 0.2101, 0.2054]


def build(times=TIMES_S, levels=LEVELS_M):
    builder = DiagramBuilder()
    ports = add_step_reference(builder, times, levels, "reference")
    builder.ExportOutput(ports.outputs["reference"], "reference")
    diagram = builder.Build()
    return diagram, diagram.CreateDefaultContext()


def output_at(diagram, context, time_s):
    context.SetTime(time_s)
    return diagram.GetOutputPort("reference").Eval(context)[0]


def test_the_reference_is_a_zero_order_hold_of_its_levels_bit_for_bit():
    """Drake's ZeroOrderHold of the same levels is the independent reference, step times too."""
    diagram, context = build()
    hold = PiecewisePolynomial.ZeroOrderHold(
        [0.0, *TIMES_S, 1e9], np.array([*LEVELS_M, LEVELS_M[-1]]).reshape(1, -1)
    )
    for time_s in [0.0, 4.999, 5.0, 5.001, 20.0, 34.999, 35.0, 100.0]:
        assert output_at(diagram, context, time_s) == hold.value(time_s)[0, 0], time_s


def test_new_levels_in_a_context_change_the_output_and_leave_the_built_default():
    diagram, context = build()
    set_step_levels(diagram, context, "reference", [0.1, 0.2, 0.3])
    assert [output_at(diagram, context, t) for t in (1.0, 6.0, 40.0)] == [0.1, 0.2, 0.3]
    np.testing.assert_array_equal(step_levels(diagram, context, "reference"), [0.1, 0.2, 0.3])
    fresh = diagram.CreateDefaultContext()
    np.testing.assert_array_equal(step_levels(diagram, fresh, "reference"), LEVELS_M)


def test_no_steps_holds_the_start_level():
    diagram, context = build(times=[], levels=[0.25])
    assert output_at(diagram, context, 50.0) == 0.25


@pytest.mark.parametrize(
    "times, levels, message",
    [
        ([5.0, 35.0], [0.1, 0.2], "2 levels for 2 step times"),
        ([35.0, 5.0], [0.1, 0.2, 0.3], "not increasing"),
        ([5.0, 5.0], [0.1, 0.2, 0.3], "not increasing"),
    ],
)
def test_malformed_steps_are_refused(times, levels, message):
    with pytest.raises(ConfigError, match=message):
        build(times, levels)


def test_writing_the_wrong_number_of_levels_is_refused():
    diagram, context = build()
    with pytest.raises(ConfigError, match="2 values; expected 3"):
        set_step_levels(diagram, context, "reference", [0.1, 0.2])
