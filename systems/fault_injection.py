"""Faults injected into the cameras and the valves, each over a time window, seeded.

A scenario's ``faults`` section names each fault (``{name: {kind, target, start_s, duration_s,
...}}``); a fault acts from ``start_s`` for ``duration_s`` on what the plant or a camera does,
never on what the controller was designed on or knows. The kinds:

- ``camera_dead``: the camera delivers no frame (``valid`` 0, distance 0), as when its cable or
  driver drops out.
- ``camera_frozen``: the camera repeats the last frame it delivered before the fault, marked
  valid (a stuck driver or a frozen image).
- ``camera_bias``: ``bias_m`` is added to every valid frame (a knocked mount; a step bias is a
  bias to the end of the run).
- ``camera_non_finite``: every frame reads NaN, marked valid (a broken depth pipeline).
- ``camera_dropouts``: each frame is lost with ``probability`` (a burst of dropouts), drawn from
  a RandomSource per frame.
- ``inlet_stuck``, ``outlet_stuck``: the valve sees ``current_a`` whatever it is commanded (0: stuck
  shut; its saturation current: stuck open).

Several faults may act on one camera or valve; where their windows overlap, the one named last in
the file acts last. A camera's faults act on its measurement after its error section, so the local
filter sees them as it would see a real camera's. All expressions are C++ (SymbolicVectorSystem):
a NaN cannot be a symbolic constant in Drake, so the NaN a non-finite frame carries comes in on an
input from a ConstantVectorSource.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

from pydrake.common import RandomDistribution
from pydrake.symbolic import Expression, Variable, if_then_else, logical_and
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import ConstantVectorSource, RandomSource

from maskless.errors import ConfigError
from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.late_random_sources import LateRandomSources, add_random_source
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
)
VALVE_FAULTS = ("inlet_stuck", "outlet_stuck")
# The field each kind uses beyond its window; the others must stay 0.
_KIND_FIELDS = {"camera_bias": "bias_m", "camera_dropouts": "probability"}
_KIND_FIELDS.update(dict.fromkeys(VALVE_FAULTS, "current_a"))
_OPTIONAL_FIELDS = ("bias_m", "probability", "current_a")


@dataclass
class FaultConfig:
    """One fault, acting from ``start_s`` for ``duration_s``.

    Attributes:
        kind: one of ``CAMERA_FAULTS`` or ``VALVE_FAULTS``.
        target: the camera a camera fault acts on (its name in ``cameras``); empty for a valve.
        start_s: when it starts (s of simulated time).
        duration_s: how long it lasts (s); past the run's end, it lasts to the end.
        bias_m: ``camera_bias``: added to each valid frame (m).
        probability: ``camera_dropouts``: each frame's chance of being lost.
        current_a: ``inlet_stuck``, ``outlet_stuck``: the current the valve sees (A).
    """

    kind: str = ""
    target: str = ""
    start_s: float = UNSET
    duration_s: float = UNSET
    bias_m: float = 0.0
    probability: float = 0.0
    current_a: float = 0.0


def validate_faults(faults: dict[str, FaultConfig], cameras: Sequence[str]) -> None:
    """Raises ConfigError naming ``faults.NAME.FIELD`` when a fault cannot be what it says."""
    for name, fault in faults.items():
        prefix = f"faults.{name}"
        refuse_out_of_range(prefix, fault, _fault_checks(fault, cameras))


def _fault_checks(fault: FaultConfig, cameras: Sequence[str]):
    """(in range, field, expected) of one fault, lazily and in order."""
    kinds = (*CAMERA_FAULTS, *VALVE_FAULTS)
    yield fault.kind in kinds, "kind", f"one of {', '.join(kinds)}"
    if fault.kind in CAMERA_FAULTS:
        yield fault.target in cameras, "target", f"a camera: {', '.join(cameras)}"
    else:
        yield fault.target == "", "target", "nothing: a valve fault names its valve in its kind"
    yield 0 <= fault.start_s < math.inf, "start_s", "a time >= 0"
    yield 0 < fault.duration_s < math.inf, "duration_s", "a positive duration"
    used = _KIND_FIELDS.get(fault.kind)
    for field_name in _OPTIONAL_FIELDS:
        if field_name != used:
            yield getattr(fault, field_name) == 0, field_name, f"0: {fault.kind} does not use it"
    if fault.kind == "camera_dropouts":
        yield 0 < fault.probability <= 1, "probability", "a probability in (0, 1]"
    if fault.kind in VALVE_FAULTS:
        yield 0 <= fault.current_a < math.inf, "current_a", "a current >= 0 (A)"


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
        frame_period_s: the camera's frame period (s): a frozen frame is held, and a dropout
            drawn, once per frame.
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
    out_distance, out_valid = Expression(distance), Expression(valid)
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
        else:  # camera_dropouts
            lost = logical_and(window, next(draws) < fault.probability)
            out_distance = if_then_else(lost, Expression(0.0), out_distance)
            out_valid = if_then_else(lost, Expression(0.0), out_valid)
    inputs = [("distance_m", [distance]), ("valid", [valid]), ("not_a_number", [nan])]
    if uniforms:
        inputs.append(("uniform", uniforms))
    return add_named_symbolic_system(
        builder,
        name,
        inputs=inputs,
        outputs=[("distance_m", [out_distance]), ("valid", [out_valid])],
        state=[held],
        dynamics=[if_then_else(frozen_now > 0.5, Expression(held), Expression(distance))],
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
