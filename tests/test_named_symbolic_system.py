"""Context parameters and banks of SymbolicVectorSystems, checked by hand and against each other."""

import numpy as np
import pytest
from pydrake.symbolic import Variable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from maskless.systems.named_symbolic_system import (
    SymbolicSystem,
    add_named_symbolic_system,
    add_symbolic_banks,
    add_symbolic_system,
    parameter_source,
)


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


PERIOD_S = 0.3


def clock_member(scale: float, period_s: float = PERIOD_S) -> SymbolicSystem:
    """A member with its own time variable, made first: x[n+1] = x[n] / 3 + s t u w + t + u.

    Its output is x + t. The product of three variables and the sum of two are where a time
    variable ordered after the member's others would change the order of the operations (and
    so the last bits).
    """
    t, u, w, x = Variable("t"), Variable("u"), Variable("w"), Variable("x")
    return SymbolicSystem(
        inputs=[("u", [u, w])],
        outputs=[("y", [x + t])],
        state=[x],
        dynamics=[x / 3.0 + scale * t * u * w + t + u],
        time=t,
        time_period=period_s,
    )


def run_members(bank: bool, made_in_reverse: bool, steps: int = 300) -> dict[str, np.ndarray]:
    """Each member's output at every step, the two members banked or added alone."""
    if made_in_reverse:  # the second member's variables are older than the first's
        second = clock_member(-0.7)
        members = {"first": clock_member(0.1), "second": second}
    else:
        members = {"first": clock_member(0.1), "second": clock_member(-0.7)}
    builder = DiagramBuilder()
    if bank:
        ports = add_symbolic_banks(builder, members)
    else:
        ports = {name: add_symbolic_system(builder, name, m) for name, m in members.items()}
    for index, name in enumerate(members):
        source = builder.AddSystem(ConstantVectorSource([1.3 + index, 0.77]))
        builder.Connect(source.get_output_port(), ports[name].inputs["u"])
        builder.ExportOutput(ports[name].outputs["y"], name)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    outputs = {name: [] for name in members}
    for step in range(steps):
        simulator.AdvanceTo(PERIOD_S * step)
        for name in members:
            outputs[name].append(diagram.GetOutputPort(name).Eval(simulator.get_context())[0])
    return {name: np.array(values) for name, values in outputs.items()}


@pytest.mark.parametrize("made_in_reverse", [False, True])
def test_a_bank_computes_what_its_members_compute_alone_bit_for_bit(made_in_reverse):
    alone = run_members(bank=False, made_in_reverse=made_in_reverse)
    banked = run_members(bank=True, made_in_reverse=made_in_reverse)
    assert alone.keys() == banked.keys()
    for name in alone:
        np.testing.assert_array_equal(banked[name], alone[name])
    # Against the closed form from x[0] = 0, t[n] = 0.3 n: after advancing to t[n] >= 0.3 the
    # output is x[n] + t[n], the updates at t[0] .. t[n-1] applied (at t = 0 the first already is).
    x, expected = 0.0, []
    for n in range(300):
        t = PERIOD_S * n
        expected.append(x + t)
        x = x / 3.0 + 0.1 * t * 1.3 * 0.77 + t + 1.3
    np.testing.assert_allclose(banked["first"][1:], expected[1:], rtol=1e-10)


def test_a_bank_is_one_system_per_period_named_by_its_members():
    builder = DiagramBuilder()
    members = {"first": clock_member(0.1), "second": clock_member(2.0)}
    ports = add_symbolic_banks(builder, {**members, "fast": clock_member(1.0, 0.1)})
    names = {system.get_name() for system in builder.GetSystems()}
    assert {"first+second", "fast"} <= names and not {"first", "second"} & names
    assert set(ports) == {"first", "second", "fast"} and set(ports["second"].outputs) == {"y"}
    builder = DiagramBuilder()
    add_symbolic_banks(builder, {"alone": clock_member(0.1)})
    assert {system.get_name() for system in builder.GetSystems()} == {"alone"}
