"""Context parameters of a SymbolicVectorSystem: defaults, writes and refusals, checked by hand."""

import numpy as np
import pytest
from pydrake.symbolic import Variable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from maskless.systems.named_symbolic_system import add_named_symbolic_system, parameter_source


def build_recurrence():
    """x[n+1] = a b x[n] + c^2 from x[0] = 0, with parameters a, b, c and d (which it ignores)."""
    x, a, b, c, d = (Variable(name) for name in "xabcd")
    builder = DiagramBuilder()
    add_named_symbolic_system(
        builder,
        "recurrence",
        inputs=[],
        outputs=[("x", [x])],
        state=[x],
        dynamics=[a * b * x + c * c],
        time_period=1.0,
        parameters=[(a, 0.5), (b, 0.5), (c, 2.0), (d, 7.0)],
    )
    return builder.Build()


def state_after(diagram, steps, values=None):
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    if values is not None:
        source = parameter_source(diagram, "recurrence")
        source.set_values(diagram.GetMutableSubsystemContext(source, context), values)
    simulator.AdvanceTo(steps - 0.5)
    recurrence = diagram.GetSubsystemByName("recurrence")
    return diagram.GetSubsystemContext(recurrence, context).get_discrete_state_vector()[0]


def test_parameters_reach_the_expressions_as_constants_computed_once():
    diagram = build_recurrence()
    source = parameter_source(diagram, "recurrence")
    # The parts of the parameters alone, a b and c^2, are two inputs of the system.
    assert source.get_output_port().size() == 2
    assert diagram.GetSubsystemByName("recurrence").get_input_port().size() == 2
    assert source.names == ("a", "b", "c", "d") and source.fixed_names == ("d",)
    assert state_after(diagram, 3) == pytest.approx(4.0 + 0.25 * (4.0 + 0.25 * 4.0))
    assert state_after(diagram, 3, [1.0, 1.0, 1.0, 7.0]) == pytest.approx(3.0)


def test_a_fixed_or_missing_parameter_is_refused():
    diagram = build_recurrence()
    source = parameter_source(diagram, "recurrence")
    context = diagram.GetMutableSubsystemContext(source, diagram.CreateDefaultContext())
    with pytest.raises(ValueError, match=r"d = 8.0 \(built with 7.0\): a number"):
        source.set_values(context, [1.0, 1.0, 1.0, 8.0])
    with pytest.raises(ValueError, match="3 values; expected 4: a, b, c, d"):
        source.set_values(context, [1.0, 1.0, 1.0])
    np.testing.assert_array_equal(source.get_values(context), [0.5, 0.5, 2.0, 7.0])
