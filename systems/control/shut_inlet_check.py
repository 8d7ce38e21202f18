"""The shut-inlet check: a pressurised bladder that keeps its air while the inlet is shut.

With the inlet commanded shut, air can only leave the bladder: through the outlet, and through its
standing leak even with the outlet shut. So a bladder holding a head loses pressure whenever its
inlet is shut: the nominal one, with both valves shut, fell from 2.9 kPa by 640 Pa in its first
half second, and still by about 370 Pa a second near 1.3 kPa (the leak scales with the
pressure). A bladder that keeps its pressure for a second with the inlet shut is being filled by
something else: an inlet stuck open.

The pressure pace check (``pressure_pace_check``) catches a valve that sticks while the loop is
still, from the step it makes. This one catches what it can miss: a noisy sensor hides the step,
or the valve sticks while the loop is moving; the loop then shuts the inlet and fights with the
outlet, and the head hovers off target with the pressure steady (measured with one count of
sensor noise: 3 of 20 stuck inlets went unseen, and in one the beam was on for 1.67 s while the
head was more than 1 mm off; ``maskless analyze faults --preset noisy_pressure_sensor``).

It uses only what the supervisor knows: the inlet command it passed on, and the pressure pace
check's tracked level (its smoothing keeps one count of sensor noise to a few pascals). It runs
while the tracked pressure is at least ``min_pressure_pa``: an empty bladder (the head resting)
has no air to lose.
"""

import math
from dataclasses import dataclass

from pydrake.symbolic import Expression, Formula, if_then_else, logical_and

from maskless.systems.config_loading import UNSET, refuse_out_of_range


@dataclass
class ShutInletConfig:
    """The shut-inlet check (module docstring); set in assets/simulation.yaml.

    Attributes:
        shut_current_a: an inlet command at or below this is shut (A).
        hold_s: the inlet shut this long in a row, the pressure must have fallen (s).
        min_fall_pa: ...by more than this (Pa).
        min_pressure_pa: the check runs while the tracked pressure is at least this (Pa, gauge).
    """

    shut_current_a: float = UNSET
    hold_s: float = UNSET
    min_fall_pa: float = UNSET
    min_pressure_pa: float = UNSET


def validate_shut_inlet(config: ShutInletConfig, prefix: str) -> None:
    """Raises ConfigError naming ``{prefix}.FIELD`` when a field is out of range."""
    positive = "a positive, finite value"
    refuse_out_of_range(
        prefix,
        config,
        (
            (
                0 <= config.shut_current_a < math.inf,
                "shut_current_a",
                "a current >= 0 (A)",
            ),
            (0 < config.hold_s < math.inf, "hold_s", positive),
            (0 < config.min_fall_pa < math.inf, "min_fall_pa", positive),
            (0 <= config.min_pressure_pa < math.inf, "min_pressure_pa", "a pressure >= 0"),
        ),
    )


def hold_ticks(config: ShutInletConfig, period_s: float) -> float:
    """``hold_s`` in whole ticks, rounded up, and at least two.

    The first tick of a shut inlet only notes the level the pressure must fall from.
    """
    return float(max(2, math.ceil(config.hold_s / period_s - 1e-9)))


@dataclass(frozen=True)
class ShutInletCheck:
    """One tick of the check, as expressions of the tick's inputs and the check's state.

    Attributes:
        shut_ticks: the next count of ticks in a row the check has run.
        start_level: the next level the pressure must fall from (Pa).
        not_shut: the inlet has been shut for ``hold_s`` and the pressure has not fallen by
            ``min_fall_pa``.
    """

    shut_ticks: Expression
    start_level: Expression
    not_shut: Formula


def shut_inlet_check(
    config: ShutInletConfig,
    *,
    period_s: float,
    shut_ticks,
    start_level,
    level,
    inlet_command_a,
    watched: Formula,
) -> ShutInletCheck:
    """The check's next state and verdict (module docstring), as symbolic expressions.

    Args:
        config: the check.
        period_s: the supervisor's tick (s).
        shut_ticks: the ticks in a row the check has run.
        start_level: the tracked level at the first of them (Pa).
        level: the tracked pressure level now (Pa; ``pressure_pace_check``).
        inlet_command_a: the inlet command passed on at the tick before: it is what the
            pressure read now shows (A).
        watched: the supervisor's conditions for the check to run (its commands passed on).
    """
    running = logical_and(
        logical_and(watched, inlet_command_a <= config.shut_current_a),
        level >= config.min_pressure_pa,
    )
    started = shut_ticks > 0.5
    not_shut = logical_and(
        logical_and(running, started),
        logical_and(
            shut_ticks + 1 >= hold_ticks(config, period_s),
            level > start_level - config.min_fall_pa,
        ),
    )
    return ShutInletCheck(
        shut_ticks=if_then_else(running, shut_ticks + 1, 0.0),
        start_level=if_then_else(
            logical_and(running, shut_ticks < 0.5), Expression(level), Expression(start_level)
        ),
        not_shut=not_shut,
    )
