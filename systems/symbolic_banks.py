"""Banks: SymbolicVectorSystems of one kind and one update period added as one system.

The cameras of a loop, or their local filters, run side by side at one period. Added as one
SymbolicVectorSystem, a bank, each keeps its named ports and its own expressions, evaluated exactly
as they would be alone. Every system with state costs each simulation step a pass of cache
invalidation over everything downstream of it, which in a feedback loop is the whole loop, and
every system and port its share of each pass: one system in place of two is cheaper (measured in
one process, the closed loop's tick took 119-125 µs with its cameras and its filters banked and
129-133 µs with each added alone).

Same bits: a sum's or a product's terms are evaluated in the order of their variables' ids, and a
member's expressions keep their own variables, except time, which the members of a bank share.
The bank uses the oldest of its members' time variables, so a member that makes its time
variable before its other variables still sees it ordered first; ``add_symbolic_banks`` refuses a
member that does not.
"""

from collections.abc import Mapping

from pydrake.symbolic import Expression, Variable
from pydrake.systems.framework import DiagramBuilder

from maskless.systems.named_symbolic_system import (
    PortMap,
    SymbolicSystem,
    add_named_symbolic_system,
    add_symbolic_system,
    as_expression,
)


def add_symbolic_banks(
    builder: DiagramBuilder, members: Mapping[str, SymbolicSystem]
) -> dict[str, PortMap]:
    """Adds ``members`` as one SymbolicVectorSystem per update period; returns their ports by name.

    Each bank is named by its members' names joined with "+" (a member alone in its period is
    added under its own name). A bank's state, inputs and outputs are its members' in turn, and
    each member's expressions are its own, so every value is what the member would compute alone,
    bit for bit (module docstring).

    Raises:
        ValueError: a member that shares a bank made its time variable after one of its others.
    """
    by_period: dict[float, dict[str, SymbolicSystem]] = {}
    for name, system in members.items():
        by_period.setdefault(system.time_period, {})[name] = system
    ports = {}
    for banked in by_period.values():
        ports |= _add_bank(builder, banked)
    return {name: ports[name] for name in members}


def _check_time_is_oldest(name: str, system: SymbolicSystem) -> None:
    if system.time is None:
        return
    others = [*system.state, *(v for _, variables in system.inputs for v in variables)]
    younger = [v.get_name() for v in others if v.get_id() < system.time.get_id()]
    if younger:
        raise ValueError(
            f"bank member {name!r}: its time variable must be made before its other variables "
            f"(made after {', '.join(younger)}), or the bank would change its sums' order"
        )


def _add_bank(builder: DiagramBuilder, members: Mapping[str, SymbolicSystem]) -> dict[str, PortMap]:
    """One SymbolicVectorSystem for ``members``, which share one update period."""
    if len(members) == 1:
        ((name, system),) = members.items()
        return {name: add_symbolic_system(builder, name, system)}
    # Only a member that shares a bank has its time replaced, so only it must make time first.
    for name, system in members.items():
        _check_time_is_oldest(name, system)
    times = [system.time for system in members.values() if system.time is not None]
    time = min(times, key=Variable.get_id) if times else None

    def shared_time(system: SymbolicSystem, expression) -> Expression:
        expression = as_expression(expression)
        if time is None or system.time is None or system.time.EqualTo(time):
            return expression
        return expression.Substitute(system.time, Expression(time))

    # The bank's ports are named by position (member, port), so no member or port name is parsed.
    ports = add_named_symbolic_system(
        builder,
        "+".join(members),
        inputs=[
            (f"{m}.{p}", variables)
            for m, system in enumerate(members.values())
            for p, (_, variables) in enumerate(system.inputs)
        ],
        outputs=[
            (f"{m}.{p}", [shared_time(system, e) for e in expressions])
            for m, system in enumerate(members.values())
            for p, (_, expressions) in enumerate(system.outputs)
        ],
        state=[variable for system in members.values() for variable in system.state],
        dynamics=[shared_time(system, e) for system in members.values() for e in system.dynamics],
        time=time,
        time_period=next(iter(members.values())).time_period,
    )
    return {
        name: PortMap(
            inputs={port: ports.inputs[f"{m}.{p}"] for p, (port, _) in enumerate(system.inputs)},
            outputs={port: ports.outputs[f"{m}.{p}"] for p, (port, _) in enumerate(system.outputs)},
        )
        for m, (name, system) in enumerate(members.items())
    }
