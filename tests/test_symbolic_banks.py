"""Banks of SymbolicVectorSystems: the same bits as each member alone, a closed form, names."""

import numpy as np
import pytest
from pydrake.symbolic import Variable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from maskless.systems.named_symbolic_system import SymbolicSystem, add_symbolic_system
from maskless.systems.symbolic_banks import add_symbolic_banks

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


def test_a_member_whose_time_is_not_its_oldest_variable_is_refused_by_name():
    x, t = Variable("x"), Variable("t")  # time made after the state
    late_time = SymbolicSystem(
        inputs=[], outputs=[("y", [x + t])], state=[x], dynamics=[x + t], time=t, time_period=0.3
    )
    with pytest.raises(ValueError, match=r"bank member 'late'.*made after x"):
        add_symbolic_banks(DiagramBuilder(), {"early": clock_member(1.0), "late": late_time})


def test_member_and_port_names_are_never_parsed():
    # A "/" or "." in a name once could route one member's ports to another.
    builder = DiagramBuilder()
    ports = add_symbolic_banks(builder, {"a/b": clock_member(1.0), "a": clock_member(2.0)})
    assert set(ports) == {"a/b", "a"}
    # Members' ports in turn: the first member's output is the bank's first.
    assert int(ports["a/b"].outputs["y"].get_index()) == 0
    assert int(ports["a"].outputs["y"].get_index()) == 1
    assert set(ports["a"].inputs) == {"u"} and set(ports["a/b"].inputs) == {"u"}
