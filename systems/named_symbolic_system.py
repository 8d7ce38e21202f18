"""A SymbolicVectorSystem behind named, sized ports, added to a builder or packaged as a Diagram.

Drake's SymbolicVectorSystem runs its expressions in C++ (several times cheaper per update than a
Python LeafSystem callback; benchmarks/system_overhead.py measures it), which is what lets the
closed loop run far faster than real time, and it supports scalar conversion, so Linearize and
AutoDiff work on it. Its ports, however, are one unnamed vector in and one out ("u0", "y0"). The
helpers here split that vector into named ports.

Every maskless component comes in two forms built by one function: ``add_*(builder, ...)`` adds its
systems to a builder and returns a ``PortMap`` (named port handles), and ``make_*(...)`` packages
the same systems as a Diagram with those port names (``diagram_form``). The closed loop uses the
first form: wrapping each system in a Diagram of its own nearly doubles the cost of a simulation
step (benchmarks/system_overhead.py), and the loop's speed target needs the flat form.

The default state of a SymbolicVectorSystem is zero and cannot be changed from Python, so the
components store their state relative to the configured initial value: a fresh Context then starts
where it should, with no set-up call a user could forget.
"""

import functools
import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.symbolic import Expression, Variable
from pydrake.systems.framework import Diagram, DiagramBuilder, InputPort, OutputPort
from pydrake.systems.primitives import Demultiplexer, Multiplexer, SymbolicVectorSystem


@dataclass
class PortMap:
    """A component's ports by name, as added to a builder.

    Attributes:
        inputs: input port name -> the port to connect (or export).
        outputs: output port name -> the port to connect (or export).
    """

    inputs: dict[str, InputPort] = field(default_factory=dict)
    outputs: dict[str, OutputPort] = field(default_factory=dict)


def as_diagram(name: str, add: Callable[[DiagramBuilder], PortMap]) -> Diagram:
    """Runs ``add`` on a fresh builder and exports every port it returns under its name."""
    builder = DiagramBuilder()
    ports = add(builder)
    for port_name, port in ports.inputs.items():
        builder.ExportInput(port, port_name)
    for port_name, port in ports.outputs.items():
        builder.ExportOutput(port, port_name)
    diagram = builder.Build()
    diagram.set_name(name)
    return diagram


def diagram_form(add: Callable[..., PortMap]) -> Callable[..., Diagram]:
    """The ``make_*`` form of an ``add_*`` component: it takes the same arguments except the
    builder and returns a Diagram named by the component's ``name`` argument.
    """
    signature = inspect.signature(add)

    def make(*args, **kwargs) -> Diagram:
        bound = signature.bind(None, *args, **kwargs)
        bound.apply_defaults()
        return as_diagram(bound.arguments["name"], lambda builder: add(builder, *args, **kwargs))

    make.__name__ = add.__name__.replace("add_", "make_", 1)
    make.__doc__ = f"``{add.__name__}`` packaged as a named Diagram (same arguments, no builder)."
    return make


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


def add_named_symbolic_system(
    builder: DiagramBuilder,
    name: str,
    *,
    inputs: Sequence[tuple[str, Sequence[Variable]]],
    outputs: Sequence[tuple[str, Sequence[Expression]]],
    state: Sequence[Variable] = (),
    dynamics: Sequence[Expression] = (),
    time: Variable | None = None,
    time_period: float = 0.0,
) -> PortMap:
    """Adds one SymbolicVectorSystem named ``name`` to ``builder``, with named ports.

    Args:
        builder: where the systems go.
        name: the SymbolicVectorSystem's name; its Multiplexer and Demultiplexer, when needed,
            are ``{name}.inputs`` and ``{name}.outputs``.
        inputs: (port name, variables) for each input port, in order.
        outputs: (port name, expressions) for each output port, in order.
        state: the state variables (discrete when ``time_period`` > 0).
        dynamics: the next state (discrete) or the derivative (continuous), one per state variable.
        time: the variable standing for time in the expressions, if any.
        time_period: the update period in s; 0 for continuous dynamics.
    """
    core = builder.AddNamedSystem(
        name,
        SymbolicVectorSystem(
            time=time,
            state=np.array(list(state), dtype=object),
            input=np.array([v for _, variables in inputs for v in variables], dtype=object),
            dynamics=np.array([_as_expression(e) for e in dynamics], dtype=object),
            output=np.array(
                [_as_expression(e) for _, expressions in outputs for e in expressions],
                dtype=object,
            ),
            time_period=time_period,
        ),
    )
    ports = PortMap()
    # A Multiplexer or Demultiplexer only where a port is shared: each extra system adds cache
    # invalidation work to every simulation step.
    if len(inputs) == 1:
        ports.inputs[inputs[0][0]] = core.get_input_port()
    elif inputs:
        mux = builder.AddNamedSystem(
            f"{name}.inputs", Multiplexer([len(variables) for _, variables in inputs])
        )
        builder.Connect(mux.get_output_port(), core.get_input_port())
        for index, (port_name, _) in enumerate(inputs):
            ports.inputs[port_name] = mux.get_input_port(index)
    if len(outputs) == 1:
        ports.outputs[outputs[0][0]] = core.get_output_port()
    else:
        demux = builder.AddNamedSystem(
            f"{name}.outputs", Demultiplexer([len(expressions) for _, expressions in outputs])
        )
        builder.Connect(core.get_output_port(), demux.get_input_port())
        for index, (port_name, _) in enumerate(outputs):
            ports.outputs[port_name] = demux.get_output_port(index)
    return ports


def _as_expression(value) -> Expression:
    """Variables and numbers as Expressions (Expression's constructor does not take one)."""
    return value if isinstance(value, Expression) else Expression(value)
