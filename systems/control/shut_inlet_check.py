"""The shut-inlet check: a pressurised bladder that keeps its air while the inlet is shut.

With the inlet commanded shut, air can only leave the bladder: through the outlet, and through its
standing leak even with the outlet shut. So a bladder holding a head loses pressure whenever its
inlet is shut: the nominal one, with both valves shut, fell from 2.9 kPa by 640 Pa in its first
half second, and by 370 Pa a second on average from 1.3 kPa down to 0.23 kPa (the leak scales
with the pressure). A bladder that keeps its pressure for a second with the inlet shut is being
filled by something else: an inlet stuck open. (That assumes nothing else loads the bladder; the
simulated patient's own motion moves the head the cameras see, not the bladder's load, so a
patient pressing the head down is not in the measurements below.)

The pressure pace check (``pressure_pace_check``) catches a valve that sticks while the loop is
still, from the step it makes. This one catches what it can miss: a noisy sensor hides the step,
or the valve sticks while the loop is moving; the loop then shuts the inlet and fights with the
outlet, and the head hovers off target with the pressure steady (measured with one count of
sensor noise: 3 of 20 stuck inlets went unseen, and in one the beam was on for 1.67 s while the
head was more than 1 mm off; ``maskless analyze faults --preset noisy_pressure_sensor``).

It uses only what the supervisor knows: the inlet command it passed on, and the pressure pace
check's tracked level (its smoothing leaves 0.69 of the readings' noise: 8.8 Pa with the noisy
preset's 12.7 Pa, one count of noise and the rounding). It runs while the tracked pressure is
at least ``min_pressure_pa``: an empty bladder (the head resting) has no air to lose.

It judges the inlet in windows of ``hold_s``: each window that passes (the pressure fell by
``min_fall_pa``) starts the next at once, so an inlet that sticks after a long shut stretch has
begun is judged a window later. A command reaches the reading two ticks after the supervisor
passes it on (the valve's spool moves at the plant's next step, the pressure at the one after),
so a window of N ticks sees the pressure fall over N - 2 of them; a window is at least three
ticks.

"Shut" is the controller's fully shut command (``shut_current_a``, 0 A): a command under the
valve's nominal starting current may still pass air on a valve whose own start is lower. The
offset-free LQG's split-range allocation shuts the inlet fully; the paper's LQG drives the
inlet only, rarely to 0 A, and has no outlet to fight a stuck inlet with.
"""

import math
from dataclasses import dataclass

from pydrake.symbolic import Expression, Formula, if_then_else, logical_and, logical_or

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.ordered_conditions import if_all
from maskless.systems.units import whole_ticks

# The fewest ticks a window can have: one to note the level, two for a command to reach it.
_FEWEST_WINDOW_TICKS = 3


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
    """``hold_s`` in whole ticks, rounded up, and at least ``_FEWEST_WINDOW_TICKS``."""
    return float(max(_FEWEST_WINDOW_TICKS, whole_ticks(config.hold_s, period_s)))


@dataclass(frozen=True)
class ShutInletCheck:
    """One tick of the check, as expressions of the tick's inputs and the check's state.

    Attributes:
        shut_ticks: the next count of ticks into the window.
        start_level: the next level the pressure must fall from (Pa).
        not_shut: the inlet has been shut for a window and the pressure has not fallen by
            ``min_fall_pa``, when all of these hold (``if_all``; the window's end first).
    """

    shut_ticks: Expression
    start_level: Expression
    not_shut: tuple[Formula, ...]


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
        shut_ticks: the ticks into the window the check is in (0: none).
        start_level: the tracked level at the window's first tick (Pa).
        level: the tracked pressure level (Pa; ``pressure_pace_check``).
        inlet_command_a: the inlet command passed on at the tick before (A).
        watched: the supervisor's conditions for the check to run (its commands passed on, a
            tracked level to compare).
    """
    # The check runs while all hold (``if_all``): the inlet shut, most often false, first.
    running = (
        inlet_command_a <= config.shut_current_a,
        level >= config.min_pressure_pa,
        watched,
    )
    # The window's first tick notes the level; its last compares with it.
    window_ends = logical_and(shut_ticks > 0.5, shut_ticks + 1 >= hold_ticks(config, period_s))
    # Running, a window opens where none is open or one ends.
    opens = logical_or(shut_ticks < 0.5, window_ends)
    return ShutInletCheck(
        shut_ticks=if_all(running, if_then_else(opens, 1.0, shut_ticks + 1), 0.0),
        start_level=if_all([*running, opens], level, start_level),
        not_shut=(window_ends, level > start_level - config.min_fall_pa, *running),
    )
