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


def clock_member(scale: float, period_s: float = 0.5) -> SymbolicSystem:
    """A member with its own time variable: x[n+1] = x[n] / 3 + scale t u, output x + t."""
    t, u, x = Variable("t"), Variable("u"), Variable("x")
    return SymbolicSystem(
        inputs=[("u", [u])],
        outputs=[("y", [x + t])],
        state=[x],
        dynamics=[x / 3.0 + scale * t * u],
        time=t,
        time_period=period_s,
    )


def run_members(bank: bool, steps: int = 7) -> dict[str, np.ndarray]:
    members = {"first": clock_member(0.1), "second": clock_member(-0.7)}
    builder = DiagramBuilder()
    if bank:
        ports = add_symbolic_banks(builder, members)
    else:
        ports = {name: add_symbolic_system(builder, name, m) for name, m in members.items()}
    for index, name in enumerate(members):
        source = builder.AddSystem(ConstantVectorSource([1.3 + index]))
        builder.Connect(source.get_output_port(), ports[name].inputs["u"])
        builder.ExportOutput(ports[name].outputs["y"], name)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(0.5 * steps)
    context = simulator.get_context()
    return {name: diagram.GetOutputPort(name).Eval(context) for name in members}


def test_a_bank_computes_what_its_members_compute_alone_bit_for_bit():
    alone, banked = run_members(bank=False), run_members(bank=True)
    assert alone.keys() == banked.keys()
    for name in alone:
        np.testing.assert_array_equal(banked[name], alone[name])
    # Against the closed form: x[n+1] = x[n] / 3 + scale t[n] u from x[0] = 0, t[n] = n / 2.
    x = 0.0
    for n in range(7):
        x = x / 3.0 + 0.1 * (0.5 * n) * 1.3
    assert banked["first"][0] == pytest.approx(x + 3.5, rel=1e-12)


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
