"""Faults injected into the cameras, valves, controller ticks and plant over time windows, seeded.

A scenario's ``faults`` section names each fault (``{name: {kind, target, start_s, duration_s,
...}}``); a fault acts from ``start_s`` for ``duration_s`` on what the plant, a camera or the
controller's output stage does, never on what the controller was designed on or knows. The kinds:

- ``camera_dead``: the camera delivers no frame (``valid`` 0, distance 0), as when its cable or
  driver drops out.
- ``camera_frozen``: the camera repeats the last frame it delivered before the fault, marked
  valid (a stuck driver or a frozen image).
- ``camera_bias``: ``bias_m`` is added to every valid frame (a knocked mount; a step bias is a
  bias to the end of the run).
- ``camera_non_finite``: every frame reads NaN, marked valid (a broken depth pipeline).
- ``camera_dropouts``: each frame is lost with ``probability`` (a burst of dropouts), drawn from
  a RandomSource per frame.
- ``latency_spike``: the camera's frames reach its filter ``latency_s`` later than its configured
  latency makes them (a stalled USB bus or frame grabber): the filter reads the frame the camera
  delivered ``latency_s`` ago, rounded to whole frames (at least half a frame, at most
  ``LATENCY_SPIKE_S``: a delay line of one frame per frame period of it lives in the Context).
  When the window closes, the frames in the line are skipped, as a driver drops a stale queue.
- ``inlet_stuck``, ``outlet_stuck``: the valve sees ``current_a`` whatever it is commanded (0: stuck
  shut; its saturation current: stuck open).
- ``missed_tick``: each controller tick in the window is missed with ``probability`` (an
  overrun real-time loop), drawn from a RandomSource per tick: the valves keep the currents they
  were commanded before it. The controller itself runs on, unaware, as it would on a real bus.
- ``supply_loss``: the supply's gauge pressure falls to ``supply_fraction`` of its nominal value
  (a failing compressor or a kinked hose; 0: lost). The model's inlet is one-way (ISO 6358 from
  the supply side), so below the bladder's pressure the inlet passes nothing rather than venting.
- ``leak_increase``: the bladder's leak conductance is ``leak_factor`` times its nominal value
  (a seam opens).

``supply_loss`` and ``leak_increase`` act on the pneumatic plant's constants (``plant:
!PneumaticPlant``); the linear plants have no supply or leak, and a scenario with either fault on
one is refused. They enter the compiled plant as factors of time on those constants
(``plant_fault_factors``), built in only when a scenario has such a fault, so a loop without one
is the plant it always was.

Several faults may act on one camera or valve; where their windows overlap, the one named last in
the file acts last, except that a latency spike acts first, on the frames as the camera delivers
them (the other faults then act on the late frames). A camera's faults act on its measurement
after its error section, so the local filter sees them as it would see a real camera's. All
expressions are C++ (SymbolicVectorSystem): a NaN cannot be a symbolic constant in Drake, so the
NaN a non-finite frame carries comes in on an input from a ConstantVectorSource.
"""

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

from pydrake.common import RandomDistribution
from pydrake.symbolic import Expression, Variable, if_then_else, logical_and
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import ConstantVectorSource, RandomSource

from maskless.errors import ConfigError
from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.late_random_sources import LateRandomSources, add_random_source
from maskless.systems.limits import LATENCY_SPIKE_S, at_least_half_a_frame
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
)

CAMERA_FAULTS = (
    "camera_dead",
    "camera_frozen",
    "camera_bias",
    "camera_non_finite",
    "camera_dropouts",
    "latency_spike",
)
VALVE_FAULTS = ("inlet_stuck", "outlet_stuck")
CONTROLLER_FAULTS = ("missed_tick",)
PLANT_FAULTS = ("supply_loss", "leak_increase")
"""Faults on the pneumatic plant's constants; the linear plants have none of them."""
# The constant (a dotted field of PneumaticParameters) each plant fault scales, and by which field.
_PLANT_CONSTANTS = {
    "supply_loss": ("supply_gauge_pressure_pa", "supply_fraction"),
    "leak_increase": ("leak_sonic_conductance_m3_s_pa", "leak_factor"),
}
# The field each kind uses beyond its window; the others must stay 0.
_KIND_FIELDS = {
    "camera_bias": "bias_m",
    "camera_dropouts": "probability",
    "latency_spike": "latency_s",
    "missed_tick": "probability",
}
_KIND_FIELDS.update(dict.fromkeys(VALVE_FAULTS, "current_a"))
_KIND_FIELDS.update({kind: factor for kind, (_, factor) in _PLANT_CONSTANTS.items()})
_OPTIONAL_FIELDS = (
    "bias_m",
    "probability",
    "current_a",
    "latency_s",
    "supply_fraction",
    "leak_factor",
)


@dataclass
class FaultConfig:
    """One fault, acting from ``start_s`` for ``duration_s``.

    Attributes:
        kind: one of ``CAMERA_FAULTS``, ``VALVE_FAULTS``, ``CONTROLLER_FAULTS`` or
            ``PLANT_FAULTS``.
        target: the camera a camera fault acts on (its name in ``cameras``); empty for the others.
        start_s: when it starts (s of simulated time).
        duration_s: how long it lasts (s); past the run's end, it lasts to the end.
        bias_m: ``camera_bias``: added to each valid frame (m).
        probability: ``camera_dropouts``: each frame's chance of being lost; ``missed_tick``:
            each controller tick's chance of being missed.
        current_a: ``inlet_stuck``, ``outlet_stuck``: the current the valve sees (A).
        latency_s: ``latency_spike``: how much later than configured the frames arrive (s).
        supply_fraction: ``supply_loss``: the supply's gauge pressure as a fraction of its
            nominal value, in [0, 1).
        leak_factor: ``leak_increase``: the leak conductance's multiple of its nominal value, > 1.
    """

    kind: str = ""
    target: str = ""
    start_s: float = UNSET
    duration_s: float = UNSET
    bias_m: float = 0.0
    probability: float = 0.0
    current_a: float = 0.0
    latency_s: float = 0.0
    supply_fraction: float = 0.0
    leak_factor: float = 0.0


def validate_faults(
    faults: dict[str, FaultConfig], cameras: Mapping[str, float], plant: str = "pneumatic"
) -> None:
    """Raises ConfigError naming ``faults.NAME.FIELD`` when a fault cannot be what it says.

    Args:
        faults: the scenario's faults by name.
        cameras: each camera's frame rate (Hz), by name (a latency spike is whole frames).
        plant: the scenario's plant ("pneumatic", "paper", "identified"): only the pneumatic
            one has the supply and the leak that ``PLANT_FAULTS`` change.
    """
    for name, fault in faults.items():
        prefix = f"faults.{name}"
        refuse_out_of_range(prefix, fault, _fault_checks(fault, cameras, plant))


def _fault_checks(fault: FaultConfig, cameras: Mapping[str, float], plant: str):
    """(in range, field, expected) of one fault, lazily and in order."""
    kinds = (*CAMERA_FAULTS, *VALVE_FAULTS, *CONTROLLER_FAULTS, *PLANT_FAULTS)
    yield fault.kind in kinds, "kind", f"one of {', '.join(kinds)}"
    if fault.kind in PLANT_FAULTS:
        constant = _PLANT_CONSTANTS[fault.kind][0]
        yield (
            plant == "pneumatic",
            "kind",
            f"a fault the {plant} plant has: {fault.kind} changes the pneumatic plant's "
            f"{constant}, which a linear model plant does not have (use plant: !PneumaticPlant)",
        )
    if fault.kind in CAMERA_FAULTS:
        yield fault.target in cameras, "target", f"a camera: {', '.join(cameras)}"
    else:
        yield fault.target == "", "target", "nothing: only a camera fault names a target"
    yield 0 <= fault.start_s < math.inf, "start_s", "a time >= 0"
    yield 0 < fault.duration_s < math.inf, "duration_s", "a positive duration"
    used = _KIND_FIELDS.get(fault.kind)
    for field_name in _OPTIONAL_FIELDS:
        if field_name != used:
            yield getattr(fault, field_name) == 0, field_name, f"0: {fault.kind} does not use it"
    yield from _kind_checks(fault, cameras)


def _kind_checks(fault: FaultConfig, cameras: Mapping[str, float]):
    """(in range, field, expected) of the field a fault's kind uses."""
    if fault.kind == "camera_dropouts":
        yield 0 < fault.probability <= 1, "probability", "a probability in (0, 1]"
    if fault.kind in VALVE_FAULTS:
        yield 0 <= fault.current_a < math.inf, "current_a", "a current >= 0 (A)"
    if fault.kind == "missed_tick":
        yield 0 < fault.probability <= 1, "probability", "a probability in (0, 1]"
    if fault.kind == "supply_loss":
        yield (
            0 <= fault.supply_fraction < 1,
            "supply_fraction",
            "a fraction in [0, 1) of the supply's gauge pressure (0: the supply is lost)",
        )
    if fault.kind == "leak_increase":
        yield 1 < fault.leak_factor < math.inf, "leak_factor", "a finite factor > 1"
    if fault.kind == "latency_spike":
        in_range, expected = at_least_half_a_frame(
            fault.latency_s, cameras[fault.target], fault.target
        )
        yield in_range, "latency_s", expected
        yield LATENCY_SPIKE_S.contains(fault.latency_s), "latency_s", LATENCY_SPIKE_S.expected()


def spike_frames(latency_s: float, frame_period_s: float) -> int:
    """A latency spike as whole frames of its camera (at least one)."""
    return max(1, math.floor(latency_s / frame_period_s + 0.5))


def _window(time: Variable, fault: FaultConfig):
    """The formula: ``time`` lies in the fault's window [start, start + duration)."""
    return logical_and(time >= fault.start_s, time < fault.start_s + fault.duration_s)


def camera_faults_of(faults: dict[str, FaultConfig], camera: str) -> list[FaultConfig]:
    """The faults that act on ``camera``, in the order they are named."""
    return [f for f in faults.values() if f.kind in CAMERA_FAULTS and f.target == camera]


def add_camera_faults(
    builder: DiagramBuilder,
    name: str,
    faults: Sequence[FaultConfig],
    camera: PortMap,
    frame_period_s: float,
    late: LateRandomSources | None = None,
) -> PortMap:
    """Adds ``faults`` to ``camera``'s measurement; returns the ports its filter reads.

    With no faults, returns ``camera`` itself and adds nothing.

    .. pydrake_system::

        name: kinect_v1.faults
        input_ports:
        - distance_m
        - valid
        output_ports:
        - distance_m
        - valid

    Args:
        builder: where the systems go.
        name: the camera's name; the systems are ``{name}.faults`` and its sources.
        faults: the faults acting on this camera (``camera_faults_of``).
        camera: the camera's ports (``distance_m``, ``valid``).
        frame_period_s: the camera's frame period (s): a frozen frame is held, a dropout
            drawn and a frame moved along a latency spike's delay line, once per frame. The
            camera's frames must change at its frame ticks (as every maskless camera's do): the
            delay line then holds the frames it delivered 1, 2, ... frames ago.
        late: where its RandomSource waits to be added after every other system, if given.
    """
    if not faults:
        return camera
    dropouts = [f for f in faults if f.kind == "camera_dropouts"]
    system = _add_camera_fault_dynamics(
        builder, f"{name}.faults", faults, frame_period_s, len(dropouts)
    )
    not_a_number = builder.AddNamedSystem(f"{name}.faults.nan", ConstantVectorSource([math.nan]))
    builder.Connect(not_a_number.get_output_port(), system.inputs["not_a_number"])
    if dropouts:
        draws = RandomSource(RandomDistribution.kUniform, len(dropouts), frame_period_s)
        add_random_source(builder, f"{name}.faults.draws", draws, system.inputs["uniform"], late)
    for port in ("distance_m", "valid"):
        builder.Connect(camera.outputs[port], system.inputs[port])
    return PortMap(outputs={port: system.outputs[port] for port in ("distance_m", "valid")})


@building_expressions
def _add_camera_fault_dynamics(
    builder: DiagramBuilder,
    name: str,
    faults: Sequence[FaultConfig],
    frame_period_s: float,
    dropout_count: int,
) -> PortMap:
    time = Variable("t")
    distance, valid = Variable("distance_m"), Variable("valid")
    nan = Variable("not_a_number")
    uniforms = [Variable(f"uniform_{k}") for k in range(dropout_count)]
    # The last frame delivered before a freeze; it follows every frame outside a frozen window.
    held = Variable("held_distance_m")
    spikes = [f for f in faults if f.kind == "latency_spike"]
    depth = max((spike_frames(f.latency_s, frame_period_s) for f in spikes), default=0)
    # The frames delivered 1..depth frames ago (the update reads the camera before its own tick),
    # only when a spike needs them: a zero default reads as an invalid frame, as before any frame.
    line_distance = [Variable(f"late_distance_m_{k}") for k in range(depth)]
    line_valid = [Variable(f"late_valid_{k}") for k in range(depth)]
    out_distance, out_valid = Expression(distance), Expression(valid)
    # A spike acts first, on the frames as the camera delivers them; the other faults act on
    # the late frames.
    for spike in spikes:
        late = spike_frames(spike.latency_s, frame_period_s) - 1
        window = _window(time, spike)
        out_distance = if_then_else(window, Expression(line_distance[late]), out_distance)
        out_valid = if_then_else(window, Expression(line_valid[late]), out_valid)
    delivered = out_distance
    frozen_now = Expression(0.0)
    draws = iter(uniforms)
    for fault in faults:
        window = _window(time, fault)
        if fault.kind == "camera_dead":
            out_distance = if_then_else(window, Expression(0.0), out_distance)
            out_valid = if_then_else(window, Expression(0.0), out_valid)
        elif fault.kind == "camera_frozen":
            out_distance = if_then_else(window, Expression(held), out_distance)
            out_valid = if_then_else(window, Expression(1.0), out_valid)
            frozen_now = if_then_else(window, Expression(1.0), frozen_now)
        elif fault.kind == "camera_bias":
            biased = if_then_else(out_valid > 0.5, out_distance + fault.bias_m, out_distance)
            out_distance = if_then_else(window, biased, out_distance)
        elif fault.kind == "camera_non_finite":
            out_distance = if_then_else(window, Expression(nan), out_distance)
            out_valid = if_then_else(window, Expression(1.0), out_valid)
        elif fault.kind == "camera_dropouts":
            lost = logical_and(window, next(draws) < fault.probability)
            out_distance = if_then_else(lost, Expression(0.0), out_distance)
            out_valid = if_then_else(lost, Expression(0.0), out_valid)
    inputs = [("distance_m", [distance]), ("valid", [valid]), ("not_a_number", [nan])]
    if uniforms:
        inputs.append(("uniform", uniforms))
    # Each frame moves one place along the delay line; the camera's newest frame enters it.
    shifted = [distance, *line_distance[:-1], valid, *line_valid[:-1]] if depth else []
    return add_named_symbolic_system(
        builder,
        name,
        inputs=inputs,
        outputs=[("distance_m", [out_distance]), ("valid", [out_valid])],
        state=[held, *line_distance, *line_valid],
        dynamics=[
            if_then_else(frozen_now > 0.5, Expression(held), delivered),
            *map(Expression, shifted),
        ],
        time=time,
        time_period=frame_period_s,
    )


def add_valve_faults(
    builder: DiagramBuilder,
    faults: dict[str, FaultConfig],
    valve: str,
    command: OutputPort,
) -> OutputPort:
    """The current valve ``valve`` ("inlet" or "outlet") sees: ``command``, or a stuck current.

    With no fault on that valve, returns ``command`` itself and adds nothing; otherwise adds
    ``{valve}_valve.faults``.
    """
    stuck = [f for f in faults.values() if f.kind == f"{valve}_stuck"]
    if not stuck:
        return command
    if valve not in ("inlet", "outlet"):
        raise ConfigError(f"no valve {valve!r}; expected inlet or outlet")
    time, current = Variable("t"), Variable("commanded_current_a")
    seen = Expression(current)
    for fault in stuck:
        seen = if_then_else(_window(time, fault), Expression(fault.current_a), seen)
    system = add_named_symbolic_system(
        builder,
        f"{valve}_valve.faults",
        inputs=[("commanded_current_a", [current])],
        outputs=[("current_a", [seen])],
        time=time,
    )
    builder.Connect(command, system.inputs["commanded_current_a"])
    return system.outputs["current_a"]


def add_controller_faults(
    builder: DiagramBuilder,
    faults: dict[str, FaultConfig],
    inlet_command: OutputPort,
    outlet_command: OutputPort,
    tick_period_s: float,
    late: LateRandomSources | None = None,
) -> tuple[OutputPort, OutputPort]:
    """The valve commands the controller delivers: its commands, except on missed ticks.

    With no ``missed_tick`` fault, returns the commands themselves and adds nothing; otherwise
    adds ``missed_ticks`` and its RandomSource ``missed_ticks.draws`` (one draw per tick and
    fault).

    .. pydrake_system::

        name: missed_ticks
        input_ports:
        - inlet_command_a
        - outlet_command_a
        - uniform
        output_ports:
        - inlet_current_a
        - outlet_current_a

    A missed tick delivers the currents delivered over the tick before it. The commands must
    change at the controller's ticks (multiples of ``tick_period_s``), as every maskless
    controller's do.

    Args:
        builder: where the systems go.
        faults: the scenario's faults; only ``missed_tick`` ones act here.
        inlet_command: the controller's inlet command (A).
        outlet_command: the controller's outlet command (A).
        tick_period_s: the controller's period (s).
        late: where the RandomSource waits to be added after every other system, if given (the
            loop adds it after every other source, so that no other draw moves).
    """
    missed = [f for f in faults.values() if f.kind == "missed_tick"]
    if not missed:
        return inlet_command, outlet_command
    system = _add_missed_tick_dynamics(builder, "missed_ticks", missed, tick_period_s)
    draws = RandomSource(RandomDistribution.kUniform, len(missed), tick_period_s)
    add_random_source(builder, "missed_ticks.draws", draws, system.inputs["uniform"], late)
    builder.Connect(inlet_command, system.inputs["inlet_command_a"])
    builder.Connect(outlet_command, system.inputs["outlet_command_a"])
    return system.outputs["inlet_current_a"], system.outputs["outlet_current_a"]


@building_expressions
def _add_missed_tick_dynamics(
    builder: DiagramBuilder, name: str, missed: Sequence[FaultConfig], tick_period_s: float
) -> PortMap:
    time = Variable("t")
    commands = [Variable("inlet_command_a"), Variable("outlet_command_a")]
    uniforms = [Variable(f"uniform_{k}") for k in range(len(missed))]
    # Whether the latest tick was missed, decided at the tick (its time, a fresh draw), and the
    # currents delivered over the tick before it. The update reads the commands as they were
    # before the tick, so what it stores is what was delivered until then.
    missed_flag = Variable("missed")
    delivered = [Variable("delivered_inlet_a"), Variable("delivered_outlet_a")]
    outputs = [
        if_then_else(missed_flag > 0.5, Expression(held), Expression(command))
        for held, command in zip(delivered, commands, strict=True)
    ]
    missed_now = Expression(0.0)
    for fault, draw in zip(missed, uniforms, strict=True):
        lost = logical_and(_window(time, fault), draw < fault.probability)
        missed_now = if_then_else(lost, Expression(1.0), missed_now)
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[
            ("inlet_command_a", [commands[0]]),
            ("outlet_command_a", [commands[1]]),
            ("uniform", uniforms),
        ],
        outputs=[("inlet_current_a", [outputs[0]]), ("outlet_current_a", [outputs[1]])],
        state=[*delivered, missed_flag],
        dynamics=[*outputs, missed_now],
        time=time,
        time_period=tick_period_s,
    )


def plant_fault_factors(
    faults: dict[str, FaultConfig],
) -> Callable[[Variable], dict[str, Expression]] | None:
    """What the plant faults do to the pneumatic plant's constants, for ``add_pneumatic_plant``.

    Returns None when no fault acts on the plant (the plant is built as ever), else a function
    that, given the variable standing for time, gives each changed constant (a dotted
    ``PneumaticParameters`` field) the factor it is multiplied by: an expression of time, 1
    outside the faults' windows. Faults on one constant multiply where their windows overlap.
    """
    acting = [f for f in faults.values() if f.kind in PLANT_FAULTS]
    if not acting:
        return None

    def factors(time: Variable) -> dict[str, Expression]:
        by_constant: dict[str, Expression] = {}
        for fault in acting:
            constant, field_name = _PLANT_CONSTANTS[fault.kind]
            scaled = if_then_else(
                _window(time, fault), Expression(getattr(fault, field_name)), Expression(1.0)
            )
            by_constant[constant] = by_constant.get(constant, Expression(1.0)) * scaled
        return by_constant

    return factors
