"""The bladder pressure's pace check: air that moves by itself, seen through a noisy sensor.

Holding the head, the loop moves the bladder's pressure smoothly, by a few pascals a tick. A valve
stuck open or shut, a seam opening or the supply lost steps it by about 100 Pa within a tick or two
while the commands stay steady (measured: the inlet stuck at 165 mA from the 147 mA the loop held
stepped the pressure by 82 Pa, then 22 Pa, over a pace of 2-4 Pa a tick;
assets/faults/inlet-stuck-open.yaml). The pressure sensor sees that at once; the cameras see the
head move a quarter of a second later.

An alpha-beta tracker follows the readings' level and pace (change per tick). Each reading's
residual against the tracker's prediction feeds two one-sided CUSUMs (Page 1954), one for rises
and one for falls, each less an allowance per tick: ``drift_pa``, plus ``per_current_pa_per_a``
per ampere the commands changed by up to the tick before (the latest change fully, the earlier
ones fading by ``COMMAND_FADE`` a tick: a command passed on at a tick moves the valve's spool at
the plant's next step and the pressure the supervisor reads at the one after, then for a few
ticks as the bladder follows; counted from the tick before, rather than from this one, the
changes gave fewer false alarms on the replay the gains were chosen on). A sum
above ``alarm_pa`` is a jump. While a sum is above zero the tracker coasts (it predicts without
correcting), so a step stays in the residuals instead of being tracked away. A reading that is no
number counts as the prediction, a residual of zero (the supervisor vents on it:
``overpressure``). The sums run only while the supervisor says the loop is watched (in tolerance,
its commands passed on) and the tracked pace is within ``still_pace_pa``; otherwise they restart
at zero.

Why not the second difference of the readings (the check before this one): it multiplies the
sensor's noise by sqrt(6) in a single tick, so with one count of noise its threshold had to clear
174 Pa, above the first tick of a stuck valve (0 of 20 stuck valves caught, `maskless analyze
faults --preset noisy_pressure_sensor`). The tracker's residual carries the noise times
``residual_noise_gain`` (1.30 for the shipped gains), and the sums add up a step's ticks.
"""

import math
from dataclasses import dataclass

from pydrake.symbolic import Expression, Formula, if_then_else, logical_and, logical_or
from pydrake.symbolic import max as symbolic_max

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.ordered_conditions import if_all

# How much of the commands' earlier changes still explains the pressure's moves, per tick.
COMMAND_FADE = 0.7
# A drift below this many residual stds of the sensor's own noise lets that noise fill the sums.
_DRIFT_NOISE_STDS = 2.0
# A reading beyond this (Pa), or NaN, is no pressure: the tracker coasts through it (the
# supervisor's overpressure check acts on it).
_READING_BOUND_PA = 1.0e7


@dataclass
class PressurePaceConfig:
    """The pace check's tracker and sums (module docstring); set in assets/simulation.yaml.

    Attributes:
        level_gain: the tracker's alpha: how much of a residual corrects its level.
        pace_gain: the tracker's beta: how much of a residual corrects its pace (per tick).
        drift_pa: the residual per tick the sums forgive with steady commands (Pa).
        per_current_pa_per_a: ...plus this much per ampere of the commands' recent changes.
        alarm_pa: a sum above this is a jump (Pa).
        still_pace_pa: the sums run while the tracked pace is within this (Pa per tick).
    """

    level_gain: float = UNSET
    pace_gain: float = UNSET
    drift_pa: float = UNSET
    per_current_pa_per_a: float = UNSET
    alarm_pa: float = UNSET
    still_pace_pa: float = UNSET


def validate_pressure_pace(config: PressurePaceConfig, prefix: str) -> None:
    """Raises ConfigError naming ``{prefix}.FIELD`` when a field is out of range.

    The gains must lie in the alpha-beta tracker's stability region, 0 < alpha < 2 and
    0 < beta < 4 - 2 alpha (Kalata 1984, "The tracking index", IEEE T-AES 20(2)).
    """
    positive = "a positive, finite value"
    refuse_out_of_range(
        prefix,
        config,
        (
            (0 < config.level_gain < 2, "level_gain", "a gain in (0, 2) (a stable tracker)"),
            (
                0 < config.pace_gain < 4 - 2 * config.level_gain,
                "pace_gain",
                f"a gain in (0, 4 - 2 level_gain = {4 - 2 * config.level_gain:.4g}) "
                "(a stable tracker)",
            ),
            (0 < config.drift_pa < math.inf, "drift_pa", positive),
            (
                0 <= config.per_current_pa_per_a < math.inf,
                "per_current_pa_per_a",
                "a value >= 0",
            ),
            (0 < config.alarm_pa < math.inf, "alarm_pa", positive),
            (0 < config.still_pace_pa < math.inf, "still_pace_pa", positive),
        ),
    )


def residual_noise_gain(level_gain: float, pace_gain: float) -> float:
    """The std of the tracker's residual per unit std of white noise in the readings.

    The square root of the sum of the squared impulse response from a reading to the residual,
    summed until its terms are negligible (the tracker is stable: ``validate_pressure_pace``).
    """
    level = pace = 0.0
    total = 0.0
    for tick in range(100_000):
        residual = (1.0 if tick == 0 else 0.0) - (level + pace)
        total += residual * residual
        level, pace = level + pace + level_gain * residual, pace + pace_gain * residual
        if tick > 10 and abs(residual) < 1e-12 and abs(level) + abs(pace) < 1e-12:
            break
    return math.sqrt(total)


def lowest_drift_pa(config: PressurePaceConfig, reading_noise_std_pa: float) -> float:
    """The smallest ``drift_pa`` a sensor with this noise (std of each reading, Pa) allows."""
    gain = residual_noise_gain(config.level_gain, config.pace_gain)
    return _DRIFT_NOISE_STDS * gain * reading_noise_std_pa


@dataclass(frozen=True)
class PaceCheck:
    """One tick of the check, as expressions of the tick's inputs and the check's state.

    Attributes:
        level: the tracker's next level (Pa).
        pace: its next pace (Pa per tick).
        rise: the rises' next sum (Pa).
        fall: the falls' next sum (Pa).
        jump: this tick's sums show a jump when all of these hold (``if_all``): the excursion
            first, then ``running`` (the latches, the estimate's band, the pace).
    """

    level: Expression
    pace: Expression
    rise: Expression
    fall: Expression
    jump: tuple[Formula, ...]


def pace_check(
    config: PressurePaceConfig,
    *,
    level,
    pace,
    rise,
    fall,
    reading,
    command_activity_a,
    first: Formula,
    watched: Formula,
) -> PaceCheck:
    """The check's next state and verdict (module docstring), as symbolic expressions.

    Args:
        config: the check.
        level: the tracker's level (Pa).
        pace: the tracker's pace (Pa per tick).
        rise: the rises' sum (Pa).
        fall: the falls' sum (Pa).
        reading: this tick's pressure reading (Pa).
        command_activity_a: the commands' changes the reading can show (A; module docstring).
        first: the first tick (the state still zero): the tracker starts at this reading, with
            no pace.
        watched: the supervisor's conditions for the sums to run, besides a still pace.
    """
    # A reading that is no number (NaN fails every comparison) leaves no residual.
    usable = abs(reading) <= _READING_BOUND_PA
    residual = if_then_else(usable, reading - level - pace, 0.0)
    allowance = config.drift_pa + config.per_current_pa_per_a * command_activity_a
    running = logical_and(watched, abs(pace) <= config.still_pace_pa)
    # Written as comparisons of the residual, not of the next sums: each use of an expression is
    # evaluated again at every tick. In the jump and the gains the excursion comes before
    # ``running``: it is rarely true, and ``running`` reads most of the supervisor's state.
    next_rise = if_then_else(running, symbolic_max(0.0, rise + residual - allowance), 0.0)
    next_fall = if_then_else(running, symbolic_max(0.0, fall - residual - allowance), 0.0)
    sum_above_zero = logical_or(residual > allowance - rise, residual < fall - allowance)
    jump = (
        logical_or(
            residual > config.alarm_pa + allowance - rise,
            residual < fall - allowance - config.alarm_pa,
        ),
        running,
    )
    # While a sum is above zero the tracker coasts. The first tick's level is its reading: the state
    # starts at zero, so a gain of one.
    level_gain = if_then_else(first, 1.0, if_all([sum_above_zero, running], 0.0, config.level_gain))
    pace_gain = if_all([sum_above_zero, running], 0.0, config.pace_gain)
    next_level = level + pace + level_gain * residual
    next_pace = if_then_else(first, 0.0, pace + pace_gain * residual)
    return PaceCheck(next_level, next_pace, next_rise, next_fall, jump)
