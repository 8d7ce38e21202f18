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

A component may describe itself as a ``SymbolicSystem`` before it is added, so that it can be
added alone (``add_symbolic_system``) or with others of its kind as one system
(``symbolic_banks``).

Constants a Context may change (a patient's head mass in a Monte Carlo run) are symbolic variables
held by a ``ParameterSource``, ``{name}.parameters``, as its numeric parameter, whose default is the
configured value. SymbolicVectorSystem's own ``parameter=`` argument would declare a numeric
parameter too, but with NaN defaults that Python cannot change, so every fresh Context would need
a set-up call.

A SymbolicVectorSystem evaluates its expressions by walking them, every node at every step, and
copies a table of all its variables at each evaluation, so constants held as variables cost time
that numbers folded into the expressions do not. Every part of the expressions that depends on the
parameters alone (a valve's flow scale, a head's weight) is therefore taken out and computed by
the ParameterSource when the parameters are written; the SymbolicVectorSystem reads only those
values, through its input vector.
"""

import functools
import inspect
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.symbolic import Evaluate, Expression, ExpressionKind, Variable, Variables
from pydrake.systems.framework import (
    BasicVector,
    Context,
    Diagram,
    DiagramBuilder,
    InputPort,
    OutputPort,
)
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Demultiplexer,
    Multiplexer,
    SymbolicVectorSystem,
)

from maskless.errors import ConfigError

# The internal name of the input that carries the constants into the system's input vector.
_CONSTANTS_INPUT = "constants"


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
    """The ``make_*`` form of an ``add_*`` component.

    It takes the same arguments except the builder and returns a Diagram named by the component's
    ``name`` argument.
    """
    signature = inspect.signature(add)

    def make(*args, **kwargs) -> Diagram:
        bound = signature.bind(None, *args, **kwargs)
        bound.apply_defaults()
        return as_diagram(bound.arguments["name"], lambda builder: add(builder, *args, **kwargs))

    make.__name__ = add.__name__.replace("add_", "make_", 1)
    make.__doc__ = f"``{add.__name__}`` packaged as a named Diagram (same arguments, no builder)."
    return make


@dataclass(frozen=True)
class SymbolicSystem:
    """A SymbolicVectorSystem's named ports, state and expressions, before it is added.

    Attributes are those of ``add_named_symbolic_system`` (a bank's members hold no parameters).
    """

    inputs: Sequence[tuple[str, Sequence[Variable]]]
    outputs: Sequence[tuple[str, Sequence[Expression]]]
    state: Sequence[Variable] = ()
    dynamics: Sequence[Expression] = ()
    time: Variable | None = None
    time_period: float = 0.0


def add_symbolic_system(builder: DiagramBuilder, name: str, system: SymbolicSystem) -> PortMap:
    """Adds ``system`` as one SymbolicVectorSystem, ``name`` (``add_named_symbolic_system``)."""
    return add_named_symbolic_system(
        builder,
        name,
        inputs=system.inputs,
        outputs=system.outputs,
        state=system.state,
        dynamics=system.dynamics,
        time=system.time,
        time_period=system.time_period,
    )


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
    parameters: Sequence[tuple[Variable, float]] = (),
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
        parameters: (variable, default value) of each constant a Context may change; the
            ParameterSource ``{name}.parameters`` holds them (``parameter_source``). Those the
            expressions do not contain are held too, fixed, as a record of the build.
    """
    source = None
    if parameters:
        splitter = _ConstantSplitter([variable for variable, _ in parameters])
        dynamics = [splitter(as_expression(e)) for e in dynamics]
        outputs = [
            (port_name, [splitter(as_expression(e)) for e in expressions])
            for port_name, expressions in outputs
        ]
        source = builder.AddNamedSystem(
            f"{name}.parameters", ParameterSource(parameters, splitter.constants)
        )
        if splitter.constants:
            inputs = [*inputs, (_CONSTANTS_INPUT, [variable for variable, _ in splitter.constants])]
    core = builder.AddNamedSystem(
        name,
        SymbolicVectorSystem(
            time=time,
            state=np.array(list(state), dtype=object),
            input=np.array([v for _, variables in inputs for v in variables], dtype=object),
            dynamics=np.array([as_expression(e) for e in dynamics], dtype=object),
            output=np.array(
                [as_expression(e) for _, expressions in outputs for e in expressions],
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
    if _CONSTANTS_INPUT in ports.inputs:
        builder.Connect(source.get_output_port(), ports.inputs.pop(_CONSTANTS_INPUT))
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


class ParameterSource(ConstantVectorSource):
    """Holds a symbolic system's parameters and the constants its expressions read.

    .. pydrake_system::

        name: ParameterSource
        output_ports:
        - y0

    Two numeric parameters: the parameters (``names`` order; the defaults are the values given)
    and, as the source value the output carries, the constants computed from them. ``set_values``
    writes both. Parameters that no constant reads (``fixed_names``) are numbers in the system's
    expressions: they are held as a record of what it was built with and cannot change.

    A ConstantVectorSource (C++) rather than a Python system computing its output from the
    parameters: with the latter, its output cached, the closed loop ran about 3 % slower.

    Args:
        parameters: (variable, default value) of each parameter.
        constants: (variable, expression of the parameters) of each value the output carries.
    """

    def __init__(
        self,
        parameters: Sequence[tuple[Variable, float]],
        constants: Sequence[tuple[Variable, Expression]],
    ):
        """Holds ``parameters`` at their defaults and outputs ``constants`` computed from them."""
        self._variables = [variable for variable, _ in parameters]
        self._defaults = np.array([value for _, value in parameters], dtype=float)
        self._expressions = np.array([expression for _, expression in constants], dtype=object)
        ConstantVectorSource.__init__(self, self._constants(self._defaults))
        self._parameter_index = self.DeclareNumericParameter(BasicVector(self._defaults))
        self.names = tuple(variable.get_name() for variable in self._variables)
        read = Variables()
        for expression in self._expressions:
            read.insert(expression.GetVariables())
        self._fixed = np.array([not read.include(variable) for variable in self._variables])
        self.fixed_names = tuple(np.array(self.names, dtype=object)[self._fixed])

    def get_values(self, context: Context) -> np.ndarray:
        """The parameters in ``context`` (``names`` order)."""
        return context.get_numeric_parameter(self._parameter_index).CopyToVector()

    def set_values(self, context: Context, values) -> None:
        """Writes the parameters (``names`` order) and the constants computed from them.

        Raises:
            ConfigError: ``values`` does not have one entry per name, or changes a fixed one.
        """
        values = np.asarray(values, dtype=float).ravel()
        if values.size != len(self.names):
            raise ConfigError(
                f"{self.get_name()}: {values.size} values; expected {len(self.names)}: "
                + ", ".join(self.names)
            )
        changed = self._fixed & (values != self._defaults)
        if changed.any():
            raise ConfigError(
                f"{self.get_name()}: "
                + ", ".join(
                    f"{name} = {value} (built with {default})"
                    for name, value, default in zip(
                        np.array(self.names, dtype=object)[changed],
                        values[changed],
                        self._defaults[changed],
                        strict=True,
                    )
                )
                + ": a number in the system's expressions, fixed when it was built"
            )
        context.get_mutable_numeric_parameter(self._parameter_index).SetFromVector(values)
        self.get_mutable_source_value(context).SetFromVector(self._constants(values))

    def _constants(self, values: np.ndarray) -> np.ndarray:
        environment = dict(zip(self._variables, values, strict=True))
        return Evaluate(self._expressions.reshape(-1, 1), environment).ravel()


def parameter_source(diagram: Diagram, name: str) -> ParameterSource:
    """The ParameterSource of the symbolic system ``name`` (added with ``parameters``).

    ``name`` is a subsystem of ``diagram``; the source's Context is
    ``diagram.GetMutableSubsystemContext(source, context)``.
    """
    return diagram.GetSubsystemByName(f"{name}.parameters")


class _ConstantSplitter:
    """Replaces each largest parameters-only part of an expression by a variable of its own.

    It keeps (variable, part) in ``constants``, one variable per distinct part.

    Each variable costs the system time at every evaluation, so a part's number factor stays in
    the expression: ``-0.5 * w`` and ``0.5 * w`` share the variable of ``w``.
    """

    def __init__(self, parameters: Sequence[Variable]):
        self._parameters = Variables(list(parameters))
        self._by_text: dict[str, list[tuple[Expression, Variable]]] = {}
        self.constants: list[tuple[Variable, Expression]] = []

    def __call__(self, expression: Expression) -> Expression:
        kind = expression.get_kind()
        if kind == ExpressionKind.Constant:
            return expression
        if self._of_parameters(expression):
            return self._constant(expression)
        if kind == ExpressionKind.Var:
            return expression
        function, arguments = expression.Unapply()
        for a in arguments:
            if not isinstance(a, Expression | float) and any(
                self._parameters.include(v) for v in a.GetFreeVariables()
            ):
                raise NotImplementedError(f"parameters in the condition of {expression}")
        if kind in (ExpressionKind.Add, ExpressionKind.Mul):
            # A sum or a product is one node over all its terms (its number first), so its
            # parameter-only terms make one constant.
            fixed = [a for a in arguments if self._of_parameters(a)]
            varying = [self(a) for a in arguments if not self._of_parameters(a)]
            return function(self._constant(as_expression(function(*fixed))), *varying)
        return function(*(self(a) if isinstance(a, Expression) else a for a in arguments))

    def _of_parameters(self, value) -> bool:
        return not isinstance(value, Expression) or value.GetVariables().IsSubsetOf(
            self._parameters
        )

    def _constant(self, expression: Expression) -> Expression:
        kind = expression.get_kind()
        if kind == ExpressionKind.Constant:
            return expression
        if kind == ExpressionKind.Mul:
            number, *factors = expression.Unapply()[1]
            if number != 1.0:
                return number * self._constant(as_expression(expression.Unapply()[0](*factors)))
        same_text = self._by_text.setdefault(expression.to_string(), [])
        for known, variable in same_text:
            if known.EqualTo(expression):
                return Expression(variable)
        variable = Variable(f"constant_{len(self.constants)}")
        same_text.append((expression, variable))
        self.constants.append((variable, expression))
        return Expression(variable)


def as_expression(value) -> Expression:
    """Variables and numbers as Expressions (Expression's constructor does not take one)."""
    return value if isinstance(value, Expression) else Expression(value)
