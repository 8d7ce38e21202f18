"""A SymbolicVectorSystem behind named, sized ports.

Drake's SymbolicVectorSystem runs its expressions in C++ (about ten times cheaper per step than a
Python LeafSystem callback, which is what lets the closed loop run far faster than real time) and
supports scalar conversion, so Linearize and AutoDiff work on it. Its ports, however, are one
unnamed vector in and one out ("u0", "y0"). This wraps it in a Diagram that splits the vector into
named ports, the convention every maskless system follows.

Its default state is zero and cannot be changed from Python, so systems built with it store their
state relative to the configured initial value: a fresh Context then starts where it should, with
no set-up call a user could forget.
"""

import functools
from collections.abc import Sequence

import numpy as np
from pydrake.symbolic import Expression, Variable
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, Multiplexer, SymbolicVectorSystem


def building_expressions(function):
    """Decorates a function that builds symbolic expressions with numpy arithmetic.

    numpy reports the CPU's floating-point status flags after each object-array operation, and
    Drake's expression code can leave the "invalid" flag set while no number is computed at all,
    so such warnings are meaningless here and are silenced for the construction only.
    """

    @functools.wraps(function)
    def wrapper(*args, **kwargs):
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            return function(*args, **kwargs)

    return wrapper


def make_named_symbolic_system(
    name: str,
    *,
    inputs: Sequence[tuple[str, Sequence[Variable]]],
    outputs: Sequence[tuple[str, Sequence[Expression]]],
    state: Sequence[Variable] = (),
    dynamics: Sequence[Expression] = (),
    time: Variable | None = None,
    time_period: float = 0.0,
) -> Diagram:
    """Builds a Diagram named ``name`` around one SymbolicVectorSystem.

    Args:
        name: the Diagram's name.
        inputs: (port name, variables) for each input port, in order.
        outputs: (port name, expressions) for each output port, in order.
        state: the state variables (discrete when ``time_period`` > 0).
        dynamics: the next state (discrete) or the derivative (continuous), one per state variable.
        time: the variable standing for time in the expressions, if any.
        time_period: the update period in s; 0 for continuous dynamics.

    Returns:
        The Diagram, with the SymbolicVectorSystem reachable as its subsystem named "dynamics".
    """
    input_variables = [v for _, variables in inputs for v in variables]
    output_expressions = [_as_expression(e) for _, expressions in outputs for e in expressions]
    core = SymbolicVectorSystem(
        time=time,
        state=np.array(list(state), dtype=object),
        input=np.array(input_variables, dtype=object),
        dynamics=np.array([_as_expression(e) for e in dynamics], dtype=object),
        output=np.array(output_expressions, dtype=object),
        time_period=time_period,
    )
    builder = DiagramBuilder()
    builder.AddNamedSystem("dynamics", core)
    # Multiplexer and Demultiplexer only where a port is shared: each extra system adds cache
    # invalidation work to every simulation step.
    if len(inputs) == 1:
        builder.ExportInput(core.get_input_port(), inputs[0][0])
    elif inputs:
        sizes = [len(variables) for _, variables in inputs]
        mux = builder.AddNamedSystem("inputs", Multiplexer(sizes))
        builder.Connect(mux.get_output_port(0), core.get_input_port())
        for index, (port_name, _) in enumerate(inputs):
            builder.ExportInput(mux.get_input_port(index), port_name)
    if len(outputs) == 1:
        builder.ExportOutput(core.get_output_port(), outputs[0][0])
    else:
        sizes = [len(expressions) for _, expressions in outputs]
        demux = builder.AddNamedSystem("outputs", Demultiplexer(sizes))
        builder.Connect(core.get_output_port(), demux.get_input_port(0))
        for index, (port_name, _) in enumerate(outputs):
            builder.ExportOutput(demux.get_output_port(index), port_name)
    diagram = builder.Build()
    diagram.set_name(name)
    return diagram


def _as_expression(value) -> Expression:
    """Variables and numbers as Expressions (Expression's constructor does not take one)."""
    return value if isinstance(value, Expression) else Expression(value)
