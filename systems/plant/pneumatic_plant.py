"""The first-principles pneumatic plant: "the real robot" the controllers are tested on.

Two forms run the same equations (``pneumatic_physics.state_derivatives``):

- ``PneumaticPlant_``: a scalar-templated LeafSystem (``TemplateSystem``) whose physical constants
  are numeric parameters, so ``Linearize``, AutoDiff and a parameter change in the Context (a head
  mass drawn in a Monte Carlo run) work on it. Analysis and design use this form.
- ``add_pneumatic_plant``: the same derivatives written out as symbolic expressions, integrated
  by a fixed-step semi-implicit scheme (``semi_implicit_step``) and run by a C++ discrete
  ``SymbolicVectorSystem``. A Python LeafSystem's derivative callback would cost tens of
  microseconds per evaluation and the closed loop must run >= 1000x faster than real time; and a
  continuous SymbolicVectorSystem cannot share a Diagram with the discrete ones of the sensors,
  filters and controller (Drake 1.51 aborts in SymbolicVectorSystem::DoCalcTimeDerivatives).
  The constants a sweep draws (``SWEPT_PARAMETERS`` by default: head, bladder, valves, supply)
  are numeric parameters of its Context too: ``set_pneumatic_parameters`` writes them, with a
  matching start, so a Monte Carlo over heads reuses one built Diagram.

Both have the port contract of every maskless plant: two valve currents in (A), the head height
above the table out (m).
"""

import dataclasses
import math
from collections.abc import Callable, Collection, Mapping
from operator import attrgetter

import numpy as np
import pydrake.math as dm
from pydrake.common.value import AbstractValue
from pydrake.symbolic import Expression, MakeVectorVariable, Variable
from pydrake.systems.framework import (
    BasicVector_,
    Context,
    Diagram,
    DiagramBuilder,
    LeafSystem_,
    NumericParameterIndex,
    ValueProducer,
)
from pydrake.systems.scalar_conversion import TemplateSystem
from scipy.optimize import brentq

from maskless.errors import ConfigError
from maskless.systems.config_loading import asset_path, load_config
from maskless.systems.limits import HEAD_MASS_KG
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
    parameter_source,
)
from maskless.systems.plant.pneumatic_physics import (
    GAUGE_PRESSURE,
    INLET_SPOOL,
    LIFT,
    LIFT_RATE,
    OUTLET_SPOOL,
    STATE_NAMES,
    PneumaticParameters,
    ValveParameters,
    gauge_pressure_rate,
    head_force_n,
    head_height_m,
    net_flow_of_state,
    net_mass_flow_kg_s,
    spool_rate,
    state_derivatives,
    valve_opening,
)

INPUT_NAMES = ("inlet_valve_current_a", "outlet_valve_current_a")


def load_pneumatic_parameters() -> PneumaticParameters:
    """The shipped plant parameters (assets/pneumatic.yaml)."""
    return load_config(PneumaticParameters, asset_path("pneumatic.yaml"))


def validate_pneumatic_parameters(p: PneumaticParameters, prefix: str = "pneumatic") -> None:
    """Raises ConfigError naming the first field that cannot describe a physical plant."""
    for holds, name, value, expected in _parameter_checks(p):
        if not holds:
            raise ConfigError(f"{prefix}.{name} = {value}: expected {expected}")


def _parameter_checks(p: PneumaticParameters):
    """(holds, field, value, expected) of each check, in the order they are reported.

    A generator, so a later check is made only once the earlier ones held.
    """
    nonnegative = {"hysteresis_fraction", "damping_n_s_m"}
    for name, value in _flat_fields(p):
        leaf = name.rsplit(".", 1)[-1]
        if leaf != "min_lift_m":
            positive = math.isfinite(value) and (value > 0 or (value == 0 and leaf in nonnegative))
            yield positive, name, value, "a positive, finite number"
    for valve_name in ("inlet", "outlet"):
        valve: ValveParameters = getattr(p, valve_name)
        yield (
            valve.saturation_current_a > valve.starting_current_a,
            f"{valve_name}.saturation_current_a",
            valve.saturation_current_a,
            f"above {valve_name}.starting_current_a ({valve.starting_current_a})",
        )
        fraction = valve.hysteresis_fraction
        yield fraction <= 0.5, f"{valve_name}.hysteresis_fraction", fraction, "<= 0.5"
        ratio = valve.critical_pressure_ratio
        yield 0 < ratio < 1, f"{valve_name}.critical_pressure_ratio", ratio, "in (0, 1)"
    leak = p.leak_critical_pressure_ratio
    yield 0 < leak < 1, "leak_critical_pressure_ratio", leak, "in (0, 1)"
    critical = max(p.inlet.critical_pressure_ratio, p.outlet.critical_pressure_ratio, leak)
    yield (
        critical < p.laminar_pressure_ratio < 1,
        "laminar_pressure_ratio",
        p.laminar_pressure_ratio,
        "above every critical pressure ratio and below 1",
    )
    yield (
        p.vacuum_absolute_pressure_pa < p.atmospheric_pressure_pa,
        "vacuum_absolute_pressure_pa",
        p.vacuum_absolute_pressure_pa,
        f"below atmospheric_pressure_pa ({p.atmospheric_pressure_pa})",
    )
    exponent = p.polytropic_exponent
    adiabatic = "in [1, 1.4] (isothermal..adiabatic)"
    yield 1.0 <= exponent <= 1.4, "polytropic_exponent", exponent, adiabatic
    for name in ("nominal_head_mass_kg", "head_mass_kg"):
        mass = getattr(p, name)
        yield HEAD_MASS_KG.contains(mass), name, mass, HEAD_MASS_KG.expected()
    below_max = f"below max_lift_m ({p.max_lift_m})"
    yield p.min_lift_m < p.max_lift_m, "min_lift_m", p.min_lift_m, below_max
    yield (
        p.rest_volume_m3 + p.volume_per_lift_m2 * p.min_lift_m > 0,
        "rest_volume_m3",
        p.rest_volume_m3,
        "a positive volume down to min_lift_m",
    )


def _nested_class(f: dataclasses.Field):
    """The dataclass a parameter field groups (a valve), or None for a number."""
    return f.default_factory if f.default_factory is not dataclasses.MISSING else None


def _dotted_names(cls, prefix: str = ""):
    """The dotted name of every number in a parameter class, in declaration order."""
    for f in dataclasses.fields(cls):
        nested = _nested_class(f)
        if nested is not None:
            yield from _dotted_names(nested, f"{prefix}{f.name}.")
        else:
            yield f"{prefix}{f.name}"


PARAMETER_NAMES = tuple(_dotted_names(PneumaticParameters))
"""The entries of ``parameter_vector``, as dotted field names (``inlet.time_constant_s``)."""


def _flat_fields(p: PneumaticParameters):
    """(dotted name, value) of every number in ``p``, in ``PARAMETER_NAMES`` order."""
    for name in PARAMETER_NAMES:
        yield name, attrgetter(name)(p)


def parameter_vector(p: PneumaticParameters) -> np.ndarray:
    """The parameters as one vector in ``PARAMETER_NAMES`` order (the plant's numeric parameter)."""
    return np.array([value for _, value in _flat_fields(p)], dtype=float)


def parameters_from_vector(values) -> PneumaticParameters:
    """Inverse of ``parameter_vector``; the entries may be any Drake scalar type.

    Raises:
        ConfigError: ``values`` does not have one entry per name of ``PARAMETER_NAMES``.
    """
    values = list(values)
    _check_size("a pneumatic parameter vector", values, PARAMETER_NAMES)
    entries = iter(values)

    def fill(cls):
        kwargs = {}
        for f in dataclasses.fields(cls):
            nested = _nested_class(f)
            kwargs[f.name] = fill(nested) if nested is not None else next(entries)
        return cls(**kwargs)

    return fill(PneumaticParameters)


def _check_size(what: str, values, names) -> None:
    if len(values) != len(names):
        raise ConfigError(
            f"{what} has {len(values)} entries; expected {len(names)}: {', '.join(names)}"
        )


def steady_gauge_pressure_pa(p: PneumaticParameters, inlet_opening, outlet_opening) -> float:
    """The gauge pressure at which the bladder's air flows balance for two valve openings.

    Between the vacuum and the supply the net inflow falls as the pressure rises; where it does
    not change sign there, the pressure ends at the end it pushes towards, and with no flow at
    all (no leak, both valves shut), at the atmosphere's.
    """
    low = p.vacuum_absolute_pressure_pa - p.atmospheric_pressure_pa

    def inflow(gauge):
        return net_mass_flow_kg_s(gauge, inlet_opening, outlet_opening, p)

    at_low, at_supply = inflow(low), inflow(p.supply_gauge_pressure_pa)
    if at_low == at_supply == 0:
        return 0.0  # sealed and shut: any pressure holds; at rest, the atmosphere's
    if at_supply >= 0:
        return p.supply_gauge_pressure_pa
    if at_low <= 0:
        return low
    return brentq(inflow, low, p.supply_gauge_pressure_pa, xtol=1e-9)


def steady_lift_m(p: PneumaticParameters, gauge_pressure: float) -> float:
    """The lift at which the head rests for a bladder gauge pressure (travel limits included).

    Past a travel limit the model's stop is a stiff spring (``limit_stiffness_n_m``) and the force
    linear in the lift, so a rest more than a travel beyond a limit (a well-sealed bladder filling
    towards the supply pressure) is solved exactly there; ``beyond_travel`` tells such a rest.
    """
    span = p.max_lift_m - p.min_lift_m
    low, high = p.min_lift_m - span, p.max_lift_m + span

    def force(lift):
        return head_force_n(gauge_pressure, lift, 0.0, p)

    for limit, outside in ((p.max_lift_m, force(high) > 0), (p.min_lift_m, force(low) < 0)):
        if outside:
            # F(limit) - (stiffness + limit stiffness) (lift - limit) = 0.
            return limit + force(limit) / (p.stiffness_n_m + p.limit_stiffness_n_m)
    return brentq(force, low, high, xtol=1e-12)


def beyond_travel(p: PneumaticParameters, state) -> bool:
    """Whether ``state`` puts the head at or past a travel limit (``min_lift_m``, ``max_lift_m``).

    There the model's stop (a stiff spring) holds the head, not the bladder's balance: no
    operating point for a design or an analysis, and no lift the patient's head could reach.
    """
    return not p.min_lift_m < state[LIFT] < p.max_lift_m


def equilibrium_state(p: PneumaticParameters, inlet_current_a: float, outlet_current_a: float):
    """The state at rest for constant coil currents, each spool at the centre of its play band."""
    gauge = steady_gauge_pressure_pa(
        p, valve_opening(inlet_current_a, p.inlet), valve_opening(outlet_current_a, p.outlet)
    )
    state = np.zeros(len(STATE_NAMES))
    state[GAUGE_PRESSURE] = gauge
    state[LIFT] = steady_lift_m(p, gauge)
    state[INLET_SPOOL] = inlet_current_a
    state[OUTLET_SPOOL] = outlet_current_a
    return state


@TemplateSystem.define("PneumaticPlant_")
def PneumaticPlant_(T):  # noqa: N802 (Drake template naming)
    """The pneumatic plant's LeafSystem class for the scalar type ``T``."""

    class Impl(LeafSystem_[T]):
        """The pneumatic plant, templated on the scalar type.

        .. pydrake_system::

            name: pneumatic_plant
            input_ports:
            - inlet_valve_current_a
            - outlet_valve_current_a
            output_ports:
            - head_height_m
            - state
            - bladder_gauge_pressure_pa

        Args:
            parameters: the plant's constants (SI); they become the numeric parameter, so a
                Context can change them.
            initial_state: the default state (``STATE_NAMES`` order); the equilibrium at zero
                currents when omitted.
        """

        def _construct(self, parameters, initial_state=None, converter=None):
            LeafSystem_[T].__init__(self, converter)
            self._parameters = parameters
            if initial_state is None:
                initial_state = equilibrium_state(parameters, 0.0, 0.0)
            self._initial_state = np.asarray(initial_state, dtype=float)
            parameter_index = self.DeclareNumericParameter(
                BasicVector_[T](parameter_vector(parameters))
            )
            # The dataclass of constants is rebuilt only when the parameter changes, not at
            # every evaluation of the dynamics.
            self._constants = self.DeclareCacheEntry(
                "constants",
                ValueProducer(
                    allocate=lambda: AbstractValue.Make(parameters),
                    calc=lambda context, value: value.set_value(
                        parameters_from_vector(context.get_numeric_parameter(0).CopyToVector())
                    ),
                ),
                {self.numeric_parameter_ticket(NumericParameterIndex(parameter_index))},
            )
            state_index = self.DeclareContinuousState(
                BasicVector_[T](self._initial_state), 0, 0, len(STATE_NAMES)
            )
            self._inputs = [self.DeclareVectorInputPort(name, 1) for name in INPUT_NAMES]
            self.DeclareVectorOutputPort("head_height_m", 1, self._calc_head_height)
            self.DeclareStateOutputPort("state", state_index)
            self.DeclareVectorOutputPort("bladder_gauge_pressure_pa", 1, self._calc_gauge_pressure)

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, other._parameters, other._initial_state, converter)

        def parameters(self, context) -> PneumaticParameters:
            """The constants in ``context`` (of this system's scalar type)."""
            return self._constants.Eval(context)

        def set_parameters(self, context, parameters: PneumaticParameters) -> None:
            """Writes new constants (say a drawn head mass) into ``context``."""
            context.get_mutable_numeric_parameter(0).SetFromVector(parameter_vector(parameters))

        def DoCalcTimeDerivatives(self, context, derivatives):  # noqa: N802 (Drake override)
            state = context.get_continuous_state_vector().CopyToVector()
            inlet, outlet = (port.Eval(context)[0] for port in self._inputs)
            rates = state_derivatives(state, inlet, outlet, self.parameters(context))
            derivatives.get_mutable_vector().SetFromVector(np.array(rates))

        def _calc_head_height(self, context, output):
            state = context.get_continuous_state_vector().CopyToVector()
            output.SetAtIndex(0, head_height_m(state, self.parameters(context)))

        def _calc_gauge_pressure(self, context, output):
            output.SetAtIndex(0, context.get_continuous_state_vector()[GAUGE_PRESSURE])

    return Impl


PneumaticPlant = PneumaticPlant_[None]


def semi_implicit_step(state, inlet_current, outlet_current, p: PneumaticParameters, step_s):
    """One fixed step of the plant, of any scalar type.

    - The head: implicit Euler on its linearised stiffness (fabric, the air spring of the bladder
      and, when touched, the travel limits) and damping, which is stable at any step; the
      head-on-air-spring mode (~12 Hz) is stiff next to the 15 Hz loop and would otherwise force
      steps of a few ms.
    - The pressure: explicit Euler with the new motion; its slowest flow time constant (~0.6 s at
      zero gauge) is many steps long.
    - Each spool: the exact decay of its first-order lag.

    Each piece of physics is evaluated once per step (the compiled expression is evaluated at
    every step, and its size is its cost).
    """
    gauge_pressure, lift = state[GAUGE_PRESSURE], state[LIFT]
    bladder = p.atmospheric_pressure_pa + gauge_pressure
    volume = p.rest_volume_m3 + p.volume_per_lift_m2 * lift
    air_spring_n_m = (
        p.contact_area_m2 * p.polytropic_exponent * bladder * p.volume_per_lift_m2 / volume
    )
    # 1 inside a travel limit, 0 well clear of it (a 0.1 mm ramp keeps it continuous).
    ramp_m = 1e-4
    in_limit = dm.min(dm.max((p.min_lift_m - lift) / ramp_m, 0.0), 1.0) + dm.min(
        dm.max((lift - p.max_lift_m) / ramp_m, 0.0), 1.0
    )
    stiffness = p.stiffness_n_m + air_spring_n_m + p.limit_stiffness_n_m * in_limit
    undamped_force = head_force_n(gauge_pressure, lift, 0.0, p)
    h_over_m = step_s / p.head_mass_kg
    lift_rate = (state[LIFT_RATE] + h_over_m * undamped_force) / (
        1.0 + h_over_m * (p.damping_n_s_m + step_s * stiffness)
    )
    next_lift = lift + step_s * lift_rate
    net_flow = net_flow_of_state(state, p)
    next_spools = []
    for spool, current, valve in zip(
        (state[INLET_SPOOL], state[OUTLET_SPOOL]),
        (inlet_current, outlet_current),
        (p.inlet, p.outlet),
        strict=True,
    ):
        # ds/dt = (outside-band error) / tau is linear in s while outside the band: exact decay.
        gain = valve.time_constant_s * (1.0 - dm.exp(-step_s / valve.time_constant_s))
        next_spools.append(spool + gain * spool_rate(current, spool, valve))
    pressure_rate = gauge_pressure_rate(gauge_pressure, next_lift, lift_rate, net_flow, p)
    return [gauge_pressure + step_s * pressure_rate, next_lift, lift_rate, *next_spools]


SWEPT_PARAMETERS = (
    "supply_gauge_pressure_pa",
    "inlet.sonic_conductance_m3_s_pa",
    "outlet.sonic_conductance_m3_s_pa",
    "leak_sonic_conductance_m3_s_pa",
    "stiffness_n_m",
    "damping_n_s_m",
    "head_mass_kg",
)
"""What a Context can change in a compiled plant by default: what differs between patients (the
head) and between installations (bladder, valves, compressor)."""

STEP_PARAMETERS = tuple(
    name for name in PARAMETER_NAMES if name not in ("rest_head_height_m", "simulation_step_s")
)
"""Every constant of the step (``semi_implicit_step``)."""

STATE_ORIGIN_NAMES = tuple(f"state_origin.{name}" for name in STATE_NAMES)
COMPILED_PARAMETER_NAMES = (*PARAMETER_NAMES, *STATE_ORIGIN_NAMES)
"""What a compiled plant's ParameterSource holds (``compiled_parameter_vector``)."""


def compiled_parameter_vector(parameters: PneumaticParameters, state_origin) -> np.ndarray:
    """What a compiled plant's ParameterSource holds (``COMPILED_PARAMETER_NAMES`` order).

    That is ``parameter_vector(parameters)``, then the state its state is stored relative to.

    Raises:
        ConfigError: ``state_origin`` does not have one entry per name of ``STATE_NAMES``.
    """
    state_origin = np.asarray(state_origin, dtype=float).ravel()
    _check_size("a plant state", state_origin, STATE_NAMES)
    return np.concatenate([parameter_vector(parameters), state_origin])


@building_expressions
def add_pneumatic_plant(
    builder: DiagramBuilder,
    parameters: PneumaticParameters,
    initial_state,
    step_s: float,
    name: str = "pneumatic_plant",
    context_parameters: Collection[str] = SWEPT_PARAMETERS,
    time_factors: Callable[[Variable], Mapping[str, Expression]] | None = None,
) -> PortMap:
    """Adds the pneumatic plant, compiled to a SymbolicVectorSystem, to ``builder``.

    .. pydrake_system::

        name: pneumatic_plant
        input_ports:
        - inlet_valve_current_a
        - outlet_valve_current_a
        output_ports:
        - head_height_m
        - state
        - bladder_gauge_pressure_pa

    Args:
        builder: where the plant goes.
        parameters: the plant's constants (SI); ``simulation_step_s`` is not used (``step_s``).
        initial_state: where a fresh Context starts (``STATE_NAMES`` order), usually
            ``equilibrium_state`` at the starting currents.
        step_s: the fixed integration step (s): the system's update period; the coil currents
            are sampled each step.
        name: the system's name; ``{name}.parameters`` is the ParameterSource that holds the
            constants (``COMPILED_PARAMETER_NAMES``), which ``set_pneumatic_parameters`` writes.
        context_parameters: the fields of ``parameters`` (``PARAMETER_NAMES``) that a Context can
            change; the others are numbers in the expressions. ``STEP_PARAMETERS`` makes every
            constant of the step changeable.
        time_factors: constants that change during the run (an injected fault: a supply lost
            for a while). Given the variable that stands for time, it returns the factor, an
            expression of time, each named constant (``PARAMETER_NAMES``) is multiplied by. None
            (the default) builds the plant without time: a plant with no such change pays
            nothing for it. ``fault_injection.plant_fault_factors`` makes one.

    Each constant a Context can change costs time at every step (a SymbolicVectorSystem copies a
    table of its variables at each evaluation, and reads a variable where it would read a
    number), hence the short default list; benchmarks/closed_loop.py measures both lists.

    The state is stored as its offset from ``initial_state``, the state origin (a
    SymbolicVectorSystem's default state is zero, so a fresh Context starts at rest). The origin
    is a number in the expressions too: as a parameter it would cost as much as a dozen more
    constants, since it enters every use of the state. So a start that matches other constants (a
    heavier head rests lower) is written into the state by ``set_pneumatic_parameters``, with
    them. The ``state`` output gives the state in absolute terms.

    Raises:
        ConfigError: ``context_parameters`` or ``time_factors`` names a field that is not one of
            ``PARAMETER_NAMES``, or ``simulation_step_s`` (the update period cannot change in a
            Context, nor in time).
    """
    changeable = [n for n in PARAMETER_NAMES if n != "simulation_step_s"]
    # Time enters the expressions only with factors of it.
    time = None if time_factors is None else Variable("t")
    factors = {} if time_factors is None else dict(time_factors(time))
    for argument, names in (("context_parameters", context_parameters), ("time_factors", factors)):
        invalid = sorted(set(names) - set(changeable))
        if invalid:
            raise ConfigError(f"{argument} {invalid}: expected some of {', '.join(changeable)}")
    origin = np.asarray(initial_state, dtype=float)
    # One variable per entry of the ParameterSource; only those of context parameters enter the
    # expressions, the others name what it holds.
    variables = [Variable(parameter_name) for parameter_name in COMPILED_PARAMETER_NAMES]
    constants = [
        Expression(variable) if parameter_name in context_parameters else value
        for (parameter_name, value), variable in zip(
            _flat_fields(parameters), variables, strict=False
        )
    ]
    p = parameters_from_vector(
        [
            constant * factors[parameter_name] if parameter_name in factors else constant
            for parameter_name, constant in zip(PARAMETER_NAMES, constants, strict=True)
        ]
    )
    offset = MakeVectorVariable(len(STATE_NAMES), "x")
    state = [origin[k] + offset[k] for k in range(len(STATE_NAMES))]
    inlet, outlet = Variable(INPUT_NAMES[0]), Variable(INPUT_NAMES[1])
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[(INPUT_NAMES[0], [inlet]), (INPUT_NAMES[1], [outlet])],
        # The gauge pressure as a port of its own: the supervisor's pressure sensor reads it, and
        # a system that only picked it out of the state would cost every step its cache work.
        outputs=[
            ("head_height_m", [head_height_m(state, p)]),
            ("state", state),
            ("bladder_gauge_pressure_pa", [state[GAUGE_PRESSURE]]),
        ],
        state=list(offset),
        dynamics=[
            next_value - start
            for next_value, start in zip(
                semi_implicit_step(state, inlet, outlet, p, step_s), origin, strict=True
            )
        ],
        time=time,
        time_period=step_s,
        parameters=list(zip(variables, compiled_parameter_vector(parameters, origin), strict=True)),
    )


make_pneumatic_plant = diagram_form(add_pneumatic_plant)


def _held_values(diagram: Diagram, context: Context, name: str) -> np.ndarray:
    source = parameter_source(diagram, name)
    return source.get_values(diagram.GetSubsystemContext(source, context))


def pneumatic_parameters(
    diagram: Diagram, context: Context, name: str = "pneumatic_plant"
) -> PneumaticParameters:
    """The constants ``context`` (``diagram``'s) holds for the compiled plant ``name`` in it."""
    return parameters_from_vector(_held_values(diagram, context, name)[: len(PARAMETER_NAMES)])


def set_pneumatic_parameters(
    diagram: Diagram,
    context: Context,
    parameters: PneumaticParameters,
    initial_state=None,
    name: str = "pneumatic_plant",
) -> None:
    """Writes new constants (a drawn head mass) into ``context``, and a start to match them.

    Write them after ``SetDefaultContext`` or ``SetRandomContext``, which restore the constants
    and the start the plant was built with.

    Args:
        diagram: a Diagram with the compiled plant ``name`` as a subsystem (the closed loop, or
            ``make_pneumatic_plant``'s Diagram).
        context: ``diagram``'s Context.
        parameters: the new constants; only the plant's context parameters may differ from the
            ones it was built with.
        initial_state: the plant's state from now on (``STATE_NAMES`` order); by default at rest
            at the coil currents the plant was built to start at (the spools of its state origin).
        name: the compiled plant's name.

    Raises:
        ConfigError: ``parameters`` cannot describe a physical plant, changes a constant that is
            a number in the plant's expressions, or ``initial_state`` has the wrong size.
    """
    validate_pneumatic_parameters(parameters)
    origin = _held_values(diagram, context, name)[len(PARAMETER_NAMES) :]
    if initial_state is None:
        initial_state = equilibrium_state(parameters, origin[INLET_SPOOL], origin[OUTLET_SPOOL])
    initial_state = np.asarray(initial_state, dtype=float).ravel()
    _check_size("initial_state", initial_state, STATE_NAMES)
    source = parameter_source(diagram, name)
    source.set_values(
        diagram.GetMutableSubsystemContext(source, context),
        compiled_parameter_vector(parameters, origin),
    )
    plant = diagram.GetSubsystemByName(name)
    diagram.GetMutableSubsystemContext(plant, context).SetDiscreteState(initial_state - origin)
