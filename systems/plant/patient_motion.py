"""The patient's own motion, added to the head height the bladder holds.

A patient is not a mannequin: the head drifts slowly as the neck relaxes, shifts by a few
millimetres within a second when the patient swallows or settles, and moves with breathing. The
cameras see, and the controller must correct, the sum of the bladder's lift and this motion.

- Drift: a constant rate (m/s), ``drift_rate_m_per_s``.
- Shifts: at random times, a Poisson process of ``shift_rate_per_s``; each moves the head by a
  normal draw of std ``shift_std_m``, reached with the time constant ``shift_time_constant_s``
  (95 % within three of them).
- Breathing: ``breathing_amplitude_m`` sin(2 pi ``breathing_frequency_hz`` t + phi), the phase phi
  drawn once per run.

All randomness comes from RandomSources (``{name}.shift_start`` and ``{name}.shift_size`` each
tick, ``{name}.phase`` once per run), so a run seeded with ``diagram.SetRandomContext`` is
reproducible bit for bit.
"""

import math
from dataclasses import dataclass

from pydrake.common import RandomDistribution
from pydrake.symbolic import Expression, MakeVectorVariable, Variable, if_then_else, sin
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import Adder, RandomSource

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.late_random_sources import LateRandomSources, add_random_source
from maskless.systems.named_symbolic_system import add_named_symbolic_system, building_expressions

# The RandomSource that draws the breathing phase samples at t = 0 and never again within a run.
_ONCE_S = 1.0e12
# A shift may start once per tick; with at most this chance per tick, two shifts a tick apart
# stay rare and the starts are close to a Poisson process.
_MAX_SHIFT_PROBABILITY = 0.05


@dataclass
class PatientMotionConfig:
    """The patient's motion; a section whose ``enabled`` is false needs nothing else.

    Attributes:
        enabled: add the motion to the head height.
        tick_s: the period at which shifts may start (s).
        drift_rate_m_per_s: the head's slow drift (m/s), signed.
        shift_rate_per_s: mean number of shifts per second.
        shift_std_m: std of a shift's size (m).
        shift_time_constant_s: how fast a shift is made (s).
        breathing_amplitude_m: peak height of the breathing motion (m).
        breathing_frequency_hz: its frequency (Hz).
    """

    enabled: bool = False
    tick_s: float = UNSET
    drift_rate_m_per_s: float = UNSET
    shift_rate_per_s: float = UNSET
    shift_std_m: float = UNSET
    shift_time_constant_s: float = UNSET
    breathing_amplitude_m: float = UNSET
    breathing_frequency_hz: float = UNSET


def validate_patient_motion(config: PatientMotionConfig) -> None:
    """Raises ConfigError naming the ``patient_motion`` field that is out of range."""
    if not config.enabled:
        return
    checks = [
        (0 < config.tick_s < math.inf, "tick_s", "a positive, finite period"),
        (math.isfinite(config.drift_rate_m_per_s), "drift_rate_m_per_s", "a finite rate"),
        (
            0 <= config.shift_rate_per_s * config.tick_s <= _MAX_SHIFT_PROBABILITY,
            "shift_rate_per_s",
            f"a rate >= 0 with at most {_MAX_SHIFT_PROBABILITY} shifts per tick on average "
            "(one draw per tick is a Poisson process only when shifts are rare per tick)",
        ),
        (0 <= config.shift_std_m < math.inf, "shift_std_m", "a finite std >= 0"),
        (
            0 < config.shift_time_constant_s < math.inf,
            "shift_time_constant_s",
            "a positive, finite time constant",
        ),
        (0 <= config.breathing_amplitude_m < math.inf, "breathing_amplitude_m", "finite, >= 0"),
        (
            0 <= config.breathing_frequency_hz < math.inf,
            "breathing_frequency_hz",
            "a finite frequency >= 0",
        ),
    ]
    refuse_out_of_range("patient_motion", config, checks)


def add_patient_motion(
    builder: DiagramBuilder,
    config: PatientMotionConfig,
    lift: OutputPort,
    name: str,
    late: LateRandomSources | None = None,
) -> OutputPort:
    """Adds the motion to ``lift`` (the bladder's head height, m); returns the head's height.

    With ``enabled`` false, returns ``lift`` itself and adds nothing. With ``late``, its
    RandomSources wait there to be added after every other system.

    .. pydrake_system::

        name: patient_motion
        output_ports:
        - motion_m
    """
    if not config.enabled:
        return lift
    validate_patient_motion(config)
    motion = _add_motion_dynamics(builder, config, name)
    sources = (
        ("shift_start", RandomDistribution.kUniform, config.tick_s, "shift_start_draw"),
        ("shift_size", RandomDistribution.kGaussian, config.tick_s, "shift_size_draw"),
        ("phase", RandomDistribution.kUniform, _ONCE_S, "phase_fraction"),
    )
    for suffix, distribution, period_s, port in sources:
        source = RandomSource(distribution, 1, period_s)
        add_random_source(builder, f"{name}.{suffix}", source, motion.inputs[port], late)
    total = builder.AddNamedSystem(f"{name}.head_height", Adder(2, 1))
    builder.Connect(lift, total.get_input_port(0))
    builder.Connect(motion.outputs["motion_m"], total.get_input_port(1))
    return total.get_output_port()


@building_expressions
def _add_motion_dynamics(builder: DiagramBuilder, config: PatientMotionConfig, name: str):
    t = Variable("t")
    (start_draw,) = MakeVectorVariable(1, "shift_start_draw")
    (size_draw,) = MakeVectorVariable(1, "shift_size_draw")
    (phase_fraction,) = MakeVectorVariable(1, "phase_fraction")
    target, level = Variable("shift_target_m"), Variable("shift_level_m")
    # A shift starts in a tick with probability rate x tick: a Poisson process, thinned per tick.
    starts = start_draw < config.shift_rate_per_s * config.tick_s
    size = config.shift_std_m * size_draw
    next_target = if_then_else(starts, target + size, Expression(target))
    blend = 1.0 - math.exp(-config.tick_s / config.shift_time_constant_s)
    breathing = config.breathing_amplitude_m * sin(
        2 * math.pi * (config.breathing_frequency_hz * t + phase_fraction)
    )
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[
            ("shift_start_draw", [start_draw]),
            ("shift_size_draw", [size_draw]),
            ("phase_fraction", [phase_fraction]),
        ],
        outputs=[("motion_m", [level + config.drift_rate_m_per_s * t + breathing])],
        state=[target, level],
        dynamics=[next_target, level + blend * (next_target - level)],
        time=t,
        time_period=config.tick_s,
    )
