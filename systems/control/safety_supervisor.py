"""The safety supervisor between the controller and the valves, and the beam-hold signal.

Each controller tick it checks what the loop knows (never the simulated truth) and latches a
reason when a check fails; a latched reason stays until the ``reset`` input is raised at a tick
while its check passes. Durations are counted in whole ticks, a limit rounded up.
Each reason has its safe action (``SAFE_ACTIONS``):

- ``camera_excluded`` (continue): the fusion uses fewer cameras than it has, but some (a camera's
  own checks flagged it, ``fault_detection``). The loop goes on with the others (degraded mode):
  holding the air would be no safer than a loop that still sees the head.
- ``no_camera`` (hold): the fusion uses no camera.
- ``cameras_disagree`` (hold): two cameras the fusion uses have disagreed for
  ``disagreement_persist_s``, and nothing says which one is wrong. A camera's own checks may name
  it first (a silent or frozen one), and the fusion leaves it out: then the loop goes on with the
  other (``camera_excluded``). A biased camera passes its checks, so its disagreement holds the
  air. The beam is held from the first tick of disagreement.
- ``estimate_uncertain`` (hold): the fused height's std is above its bound.
- ``outside_travel`` (hold): a camera sees the head outside the bladder's travel, widened by
  ``travel_margin_m`` (or the estimate is not finite): no height the bladder can give.
- ``non_finite_command`` (hold): a valve command is NaN or infinite. It is never passed on: the
  held currents replace it in the same tick.
- ``inlet_full_too_long`` (continue): the inlet has been fully open for ``max_full_inlet_s`` in a
  row (a valve stuck, a lost supply or a leak the loop cannot beat, or a target out of the
  valves' reach). The loop goes on: fully open is the most it can do, and held currents would
  drop the head back to where they were averaged (measured in the standard population with held
  currents: p95 up to 30 mm where the head was being lifted 25-30 mm for over 20 s).
- ``pressure_jump`` (continue): the bladder's pressure stepped away from the pace it held, by more
  than the loop's own commands explain, while the loop was still and its valves got its commands
  (``pressure_pace_check``, configured by ``pressure_pace``): air moving by itself, a valve
  stuck open or shut, a seam opening, the supply lost. The loop goes on: it is what can still
  fight a stuck inlet with the outlet (held currents could not: measured, the head rose 6.2 mm
  holding and 4.3 mm with the loop on, assets/faults/inlet-stuck-open.yaml).
- ``inlet_not_shut`` (continue): the inlet has been commanded shut for ``shut_inlet.hold_s`` and
  the pressurised bladder has not lost air (``shut_inlet_check``): something fills it, an inlet
  stuck open. The loop goes on, as for ``pressure_jump``: the outlet is what can still fight it
  (the paper's LQG drives no outlet; its beam stays held).
- ``overpressure`` (vent): the bladder's gauge pressure (its sensor) is above
  ``max_gauge_pressure_pa``, or the sensor reads no number.

The estimate's checks start after ``start_grace_s``: the filters begin from a guess and are
uncertain by design for their first frames.

Hold: the valves keep the currents the loop commanded while nothing was latched and the inlet
was not fully open, averaged over ``hold_time_constant_s`` (an exponential average: the few ticks
a fault misleads the controller before it is caught barely move it). Open loop, they hold the head
about where the loop last had it. Shutting both valves would not: the bladder's standing leak sets
where the head rests for a given inlet opening (``pneumatic.yaml``), so a shut bladder drains
(measured: both cameras lost, both valves shut, the head dropped 11 mm in the next minute).
Vent: the inlet shuts and the outlet opens fully, so the bladder empties and the head comes down to
its resting height: a bladder above its pressure limit may burst, and resting on the empty bladder
is where the patient lay down.

``beam_hold`` is 1 whenever a reason is latched or a command is not finite, and until the error
that the controller's model-based estimate shows (``estimated_head_height_m``) has stayed within
the tolerance less ``estimate_margin_m`` for ``beam_dwell_s``, and the fused camera estimate's
error is within ``fused_error_band_m`` (a head that moves faster than the model's estimate
follows shows there first). A linac gates on it.

The decisions are taken at ticks and held as state, and the pressure is read only at ticks: the
plant reads the valve currents at every integrator step, and an output that depended on the
plant's continuous state would be evaluated at each.
"""

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.symbolic import (
    Expression,
    Variable,
    if_then_else,
    logical_and,
    logical_not,
)
from pydrake.systems.framework import DiagramBuilder

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.control.pressure_pace_check import (
    COMMAND_FADE,
    PressurePaceConfig,
    pace_check,
    validate_pressure_pace,
)
from maskless.systems.control.shut_inlet_check import (
    ShutInletConfig,
    shut_inlet_check,
    validate_shut_inlet,
)
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)
from maskless.systems.ordered_conditions import if_all
from maskless.systems.units import whole_ticks

CONTINUE, HOLD, VENT = "continue", "hold", "vent"
# Each reason and its safe action (the module docstring says why).
SAFE_ACTIONS = {
    "camera_excluded": CONTINUE,
    "no_camera": HOLD,
    "cameras_disagree": HOLD,
    "estimate_uncertain": HOLD,
    "outside_travel": HOLD,
    "non_finite_command": HOLD,
    "inlet_full_too_long": CONTINUE,
    "pressure_jump": CONTINUE,
    "inlet_not_shut": CONTINUE,
    "overpressure": VENT,
}
REASONS = tuple(SAFE_ACTIONS)
# The ``mode`` output: what the valves get.
MODES = ("pass", HOLD, VENT)
# The outputs that say what the supervisor decided (the rest are the valves' currents).
SAFETY_STATUS = ("reasons", "mode", "beam_hold")
# A command beyond this is no current a valve driver takes (A): treated as non-finite. NaN fails
# every comparison, so "inside the bound" is false for it too.
_COMMAND_BOUND_A = 1.0e3


@dataclass
class SafetyConfig:
    """The supervisor's limits; a section not ``enabled`` needs nothing else.

    Attributes:
        enabled: put the supervisor between the controller and the valves.
        start_grace_s: the estimate's checks start after this (s).
        travel_margin_m: how far outside the bladder's travel an estimate may lie (m).
        max_gauge_pressure_pa: the bladder's pressure limit (Pa, gauge).
        max_full_inlet_s: the longest the inlet may be fully open in a row (s).
        disagreement_persist_s: how long two cameras may disagree before the air is held (s).
        pressure_pace: the check of the pressure's pace (``pressure_pace_check``).
        shut_inlet: the check that a shut inlet lets the pressure fall (``shut_inlet_check``).
        estimate_margin_m: the beam is held while the controller's estimated error is within
            this much of the tolerance (m).
        fused_error_band_m: ...or while the fused camera estimate's error is beyond this (m).
        beam_dwell_s: ...and until the estimated error has stayed inside for this long (s).
        hold_time_constant_s: the time constant of the average of the commands held (s).
    """

    enabled: bool = False
    start_grace_s: float = UNSET
    travel_margin_m: float = UNSET
    max_gauge_pressure_pa: float = UNSET
    max_full_inlet_s: float = UNSET
    disagreement_persist_s: float = UNSET
    estimate_margin_m: float = UNSET
    fused_error_band_m: float = UNSET
    beam_dwell_s: float = UNSET
    hold_time_constant_s: float = UNSET
    pressure_pace: PressurePaceConfig = field(default_factory=PressurePaceConfig)
    shut_inlet: ShutInletConfig = field(default_factory=ShutInletConfig)


def validate_safety(config: SafetyConfig, tolerance_m: float) -> None:
    """Raises ConfigError naming ``safety.FIELD`` when a limit is out of range."""
    if not config.enabled:
        return
    positive = "a positive, finite value"
    refuse_out_of_range(
        "safety",
        config,
        [
            (0 <= config.start_grace_s < math.inf, "start_grace_s", "a time >= 0"),
            (0 <= config.travel_margin_m < math.inf, "travel_margin_m", "a margin >= 0"),
            (0 < config.max_gauge_pressure_pa < math.inf, "max_gauge_pressure_pa", positive),
            (0 < config.max_full_inlet_s < math.inf, "max_full_inlet_s", positive),
            (
                0 <= config.disagreement_persist_s < math.inf,
                "disagreement_persist_s",
                "a time >= 0",
            ),
            (
                0 <= config.estimate_margin_m < tolerance_m,
                "estimate_margin_m",
                f"a margin >= 0 and below metrics.tolerance_m ({tolerance_m} m)",
            ),
            (0 < config.fused_error_band_m < math.inf, "fused_error_band_m", positive),
            (0 <= config.beam_dwell_s < math.inf, "beam_dwell_s", "a time >= 0"),
            (0 < config.hold_time_constant_s < math.inf, "hold_time_constant_s", positive),
        ],
    )
    validate_pressure_pace(config.pressure_pace, "safety.pressure_pace")
    validate_shut_inlet(config.shut_inlet, "safety.shut_inlet")


def safety_states(mode: np.ndarray, reasons: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample of the ``mode`` and ``reasons`` outputs: the state's name and the latched reasons.

    The state is ``normal``, ``degraded`` (only reasons whose action is to continue are latched),
    ``holding`` or ``venting``; the reasons are comma-separated, empty when none.
    """
    latched = np.asarray(reasons) > 0.5
    # One name per distinct set of latched reasons (a run has a handful), not one per sample.
    patterns, which = np.unique(latched.T, axis=0, return_inverse=True)
    spelled = [",".join(r for r, on in zip(REASONS, p, strict=True) if on) for p in patterns]
    names = np.array(spelled, dtype=object)[np.ravel(which).astype(int)]
    state = np.where(latched.any(axis=0), "degraded", "normal").astype(object)
    state[np.asarray(mode) > 0.5] = "holding"
    state[np.asarray(mode) > 1.5] = "venting"
    return state, names


def _within(value, low, high):
    """``low <= value <= high``, false for NaN (every comparison with NaN is)."""
    return logical_and(value >= low, value <= high)


def _within_band(value, half_width):
    """``-half_width <= value <= half_width``, false for NaN; ``value`` evaluated once."""
    return abs(value) <= half_width


@building_expressions
def add_safety_supervisor(
    builder: DiagramBuilder,
    config: SafetyConfig,
    *,
    period_s: float,
    camera_count: int,
    head_height_limits_m: tuple[float, float],
    tolerance_m: float,
    inlet_saturation_a: float,
    outlet_saturation_a: float,
    name: str = "safety",
) -> PortMap:
    """Adds the supervisor (module docstring).

    .. pydrake_system::

        name: safety
        input_ports:
        - inlet_command_a
        - outlet_command_a
        - fused_estimated_state
        - fusion_health
        - reference_head_height_m
        - estimated_head_height_m
        - bladder_gauge_pressure_pa
        - reset
        output_ports:
        - inlet_valve_current_a
        - outlet_valve_current_a
        - reasons
        - mode
        - beam_hold

    Args:
        builder: where it goes.
        config: its limits.
        period_s: its tick, the controller's (s).
        camera_count: the cameras the fusion has.
        head_height_limits_m: the head heights the bladder's travel allows (m).
        tolerance_m: the clinical band for the beam hold (m).
        inlet_saturation_a: the inlet's fully open current (A).
        outlet_saturation_a: the outlet's fully open current (A).
        name: the system's name.

    ``reasons`` holds one latched flag per ``REASONS`` entry; ``mode`` is the index in ``MODES``
    of what the valves get (the commands, the held currents, or venting).

    One SymbolicVectorSystem: splitting the checks, the latches and the valves' gate into systems
    of their own measured no faster (each system adds its own cache and event work at every tick).
    """
    inlet, outlet = Variable("inlet_command_a"), Variable("outlet_command_a")
    fused_height, fused_velocity = Variable("fused_height_m"), Variable("fused_velocity_m_s")
    tracks_used, disagreement, uncertain = (
        Variable(n) for n in ("tracks_used", "disagreement", "uncertain")
    )
    reference, estimated, pressure, reset = (
        Variable(n)
        for n in (
            "reference_head_height_m",
            "estimated_head_height_m",
            "gauge_pressure_pa",
            "reset",
        )
    )
    latched = {reason: Variable(f"latched_{reason}") for reason in REASONS}
    # What the valves get follows from the latched reasons alone, so it is no state of its own:
    # the update would evaluate every check again to set it.
    venting = _acting(latched, VENT)
    hold_latched = _acting(latched, HOLD)
    held_inlet, held_outlet = Variable("held_inlet_a"), Variable("held_outlet_a")
    averaging = Variable("averaging")  # 1 once the held currents' average has its first command
    # Durations as whole ticks: a sum of float periods drifts, and a limit that is no whole number
    # of ticks is rounded up (0.5 s at 15 Hz: 8 ticks).
    elapsed, full_inlet, inside, disagreeing = (
        Variable(f"{n}_ticks") for n in ("elapsed", "full_inlet", "inside", "disagreeing")
    )

    def ticks(limit_s: float) -> float:
        return float(whole_ticks(limit_s, period_s))

    beam_allowed = Variable("beam_allowed")
    pressure_level, pressure_pace = Variable("pressure_level_pa"), Variable("pressure_pace_pa")
    pressure_rise, pressure_fall = Variable("pressure_rise_pa"), Variable("pressure_fall_pa")
    last_inlet, last_outlet = Variable("last_inlet_command_a"), Variable("last_outlet_command_a")
    last_activity = Variable("last_command_activity_a")
    shut_ticks, shut_start = Variable("shut_inlet_ticks"), Variable("shut_inlet_start_level_pa")
    low, high = head_height_limits_m
    margin = config.travel_margin_m
    commands_finite = _commands_finite(inlet, outlet)
    cleared = reset > 0.5
    # The commands' recent changes (A; pressure_pace_check). Only finite commands are remembered,
    # and a reset forgets them.
    command_activity = (
        abs(inlet - last_inlet) + abs(outlet - last_outlet) + COMMAND_FADE * last_activity
    )
    inlet_out, outlet_out = _valve_currents(
        inlet,
        outlet,
        hold_latched,
        venting,
        held_inlet,
        held_outlet,
        commands_finite,
        outlet_saturation_a,
    )
    at_full_inlet = inlet_out >= inlet_saturation_a
    watching = elapsed >= ticks(config.start_grace_s)
    # The pressure checks judge the loop's own commands: not while the supervisor itself moves
    # the air (holding or venting); and from the third tick (the tracker starts at the first
    # reading and has a pace from the second).
    # (One sum of the reasons that hold or vent, and one count of ticks: the same truth as
    # "not supervising, watching, from the third tick", the latched flags being 0 or 1, with
    # fewer nodes to evaluate.)
    commands_tracked = logical_and(
        _latched_count(latched, [r for r in REASONS if SAFE_ACTIONS[r] != CONTINUE]) < 0.5,
        elapsed >= max(2.0, ticks(config.start_grace_s)),
    )
    pressure_check = pace_check(
        config.pressure_pace,
        level=pressure_level,
        pace=pressure_pace,
        rise=pressure_rise,
        fall=pressure_fall,
        reading=pressure,
        # The commands' changes up to the tick before (pressure_pace_check says why).
        command_activity_a=last_activity,
        first=elapsed < 0.5,
        watched=logical_and(commands_tracked, _within_band(estimated - reference, tolerance_m)),
    )
    shut_check = shut_inlet_check(
        config.shut_inlet,
        period_s=period_s,
        shut_ticks=shut_ticks,
        start_level=shut_start,
        # The tracker's level as of the tick before (the state costs nothing to evaluate again),
        # and the command passed on then.
        level=pressure_level,
        inlet_command_a=last_inlet,
        watched=commands_tracked,
    )
    seen = tracks_used > 0.5
    # Each check fails when all its conditions hold, tested in order (``if_all``): the one most
    # often false first, so that on most ticks the others are never evaluated.
    failing = {
        "camera_excluded": (tracks_used < camera_count - 0.5, seen, watching),
        "no_camera": (logical_not(seen), watching),
        "cameras_disagree": (
            disagreement > 0.5,
            disagreeing + 1 >= ticks(config.disagreement_persist_s),
            watching,
        ),
        "estimate_uncertain": (uncertain > 0.5, watching),
        "outside_travel": (
            logical_not(_within(fused_height, low - margin, high + margin)),
            seen,
            watching,
        ),
        "non_finite_command": (logical_not(commands_finite),),
        "inlet_full_too_long": (full_inlet + 1 >= ticks(config.max_full_inlet_s), at_full_inlet),
        "pressure_jump": pressure_check.jump,
        "inlet_not_shut": shut_check.not_shut,
        "overpressure": (logical_not(pressure <= config.max_gauge_pressure_pa),),
    }
    band = tolerance_m - config.estimate_margin_m
    # On target: both estimates within their bands, and the cameras agree.
    on_target = logical_and(
        logical_and(
            _within_band(estimated - reference, band),
            _within_band(fused_height - reference, config.fused_error_band_m),
        ),
        disagreement < 0.5,
    )
    # A reset clears the reasons whose checks pass now; one still failing stays latched.
    after_reset = {r: if_then_else(cleared, 0.0, Expression(latched[r])) for r in REASONS}
    next_latched = [if_all(failing[r], 1.0, after_reset[r]) for r in REASONS]

    nothing_latched = _latched_count(latched, REASONS) < 0.5
    # The held currents follow the commands that pass while nothing was latched and the inlet is
    # not fully open (the tick that first sees a fault still counts: its command was computed a
    # tick before); the average starts at the first such command.
    # (With nothing latched and finite commands, the inlet passed on is the command; the
    # saturation current is a number, validated with the plant.)
    keep = (
        logical_not(cleared),
        inlet < inlet_saturation_a,
        nothing_latched,
        commands_finite,
    )
    weight = if_then_else(
        averaging < 0.5, 1.0, 1.0 - math.exp(-period_s / config.hold_time_constant_s)
    )
    next_held = [
        if_all(keep, held + weight * (command - held), held)
        for held, command in ((held_inlet, inlet), (held_outlet, outlet))
    ]
    next_inside = if_then_else(on_target, inside + 1, 0.0)
    next_allowed = if_then_else(
        logical_and(
            commands_finite, logical_and(on_target, inside + 1 >= ticks(config.beam_dwell_s))
        ),
        1.0,
        0.0,
    )
    # Checked again on this instant's inputs: a reference that steps at a tick holds the beam from
    # that instant; so does a command that is not finite. The beam waits for a reset too: a
    # latched reason holds it whatever the estimate says.
    beam_hold = if_then_else(
        logical_and(
            logical_and(beam_allowed > 0.5, nothing_latched),
            logical_and(on_target, commands_finite),
        ),
        0.0,
        1.0,
    )
    remembered = [
        if_then_else(commands_finite, Expression(command), Expression(last))
        for command, last in ((inlet, last_inlet), (outlet, last_outlet))
    ]
    next_activity = if_then_else(
        cleared,
        0.0,
        if_then_else(commands_finite, command_activity, Expression(last_activity)),
    )
    state_and_next = [
        (held_inlet, next_held[0]),
        (held_outlet, next_held[1]),
        *zip(latched.values(), next_latched, strict=True),
        # Once 1, it stays 1: the keep conditions are not evaluated again.
        (averaging, if_then_else(averaging > 0.5, averaging, if_all(keep, 1.0, averaging))),
        (elapsed, elapsed + 1),
        (full_inlet, if_then_else(at_full_inlet, full_inlet + 1, 0.0)),
        (inside, next_inside),
        (beam_allowed, next_allowed),
        (pressure_level, pressure_check.level),
        (pressure_pace, pressure_check.pace),
        (pressure_rise, pressure_check.rise),
        (pressure_fall, pressure_check.fall),
        (last_inlet, remembered[0]),
        (last_outlet, remembered[1]),
        (last_activity, next_activity),
        (disagreeing, if_then_else(disagreement > 0.5, disagreeing + 1, 0.0)),
        (shut_ticks, shut_check.shut_ticks),
        (shut_start, shut_check.start_level),
    ]
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[
            ("inlet_command_a", [inlet]),
            ("outlet_command_a", [outlet]),
            ("fused_estimated_state", [fused_height, fused_velocity]),
            ("fusion_health", [tracks_used, disagreement, uncertain]),
            ("reference_head_height_m", [reference]),
            ("estimated_head_height_m", [estimated]),
            ("bladder_gauge_pressure_pa", [pressure]),
            ("reset", [reset]),
        ],
        outputs=[
            ("inlet_valve_current_a", [inlet_out]),
            ("outlet_valve_current_a", [outlet_out]),
            ("reasons", [Expression(latched[r]) for r in REASONS]),
            ("mode", [if_then_else(venting, 2.0, if_then_else(hold_latched, 1.0, 0.0))]),
            ("beam_hold", [beam_hold]),
        ],
        state=[variable for variable, _ in state_and_next],
        dynamics=[update for _, update in state_and_next],
        time_period=period_s,
    )


make_safety_supervisor = diagram_form(add_safety_supervisor)


def _latched_count(latched, reasons):
    """How many of ``reasons`` are latched."""
    return sum(Expression(latched[r]) for r in reasons)


def _acting(latched, action):
    """A reason whose safe action is ``action`` is latched."""
    return _latched_count(latched, [r for r in REASONS if SAFE_ACTIONS[r] == action]) > 0.5


def _commands_finite(inlet, outlet):
    """Both commands are numbers a valve driver takes."""
    return logical_and(
        _within_band(inlet, _COMMAND_BOUND_A),
        _within_band(outlet, _COMMAND_BOUND_A),
    )


def _valve_currents(
    inlet, outlet, hold_latched, venting, held_inlet, held_outlet, commands_finite, outlet_full_a
):
    """What the valves get: the commands, the held currents, or venting (``MODES``).

    Venting is tested first, so the hold reasons are read only when it is not latched.
    """

    def passed_on(command, held):
        return if_then_else(
            hold_latched, held, if_then_else(commands_finite, command, Expression(held))
        )

    inlet_out = if_then_else(venting, 0.0, passed_on(inlet, held_inlet))
    outlet_out = if_then_else(venting, outlet_full_a, passed_on(outlet, held_outlet))
    return inlet_out, outlet_out
