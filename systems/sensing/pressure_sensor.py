"""The bladder's pressure sensor: the gauge pressure read through a converter, with its noise.

A real positioner has one (issue 13), and the safety supervisor's overpressure and pressure-pace
checks read it, not the plant's state. The reading is the gauge pressure plus white noise,
rounded to the converter's count and held within the sensor's range:

    reading = clamp(q * round((p + sigma * n) / q), lowest, highest),   n ~ N(0, 1) per tick

A resolution q of 0 reads the pressure unrounded and a sigma of 0 adds no noise (and no
RandomSource): the ideal sensor. A noisy sensor's RandomSource is added after every other source
(``late_random_sources``), so switching the noise on changes no camera's draws.

The pace check (``pressure_pace_check``) must forgive what the sensor alone moves its readings by:
``reading_noise_std_pa`` is that noise's std, the rounding counted as a uniform error of one count.
"""

import math
from dataclasses import dataclass

from pydrake.common import RandomDistribution
from pydrake.symbolic import Expression, Variable, floor
from pydrake.symbolic import max as symbolic_max
from pydrake.symbolic import min as symbolic_min
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import RandomSource

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.late_random_sources import LateRandomSources, add_random_source
from maskless.systems.named_symbolic_system import add_named_symbolic_system


@dataclass
class PressureSensorConfig:
    """The bladder's gauge pressure sensor.

    Attributes:
        resolution_pa: one count of its converter (Pa); 0 for a reading that is not rounded.
        noise_std_pa: white noise on each reading, before rounding (Pa); 0 for none.
        lowest_pa: the lowest gauge pressure it reads (Pa); below, it reads this.
        highest_pa: the highest it reads (Pa); above, it reads this.
    """

    resolution_pa: float = UNSET
    noise_std_pa: float = UNSET
    lowest_pa: float = UNSET
    highest_pa: float = UNSET


def validate_pressure_sensor(config: PressureSensorConfig, prefix: str = "pressure_sensor") -> None:
    """ConfigError naming the field for a resolution, noise or range out of bounds."""
    refuse_out_of_range(
        prefix,
        config,
        (
            (0 <= config.resolution_pa < math.inf, "resolution_pa", "a finite count >= 0 (Pa)"),
            (0 <= config.noise_std_pa < math.inf, "noise_std_pa", "a finite std >= 0 (Pa)"),
            (math.isfinite(config.lowest_pa), "lowest_pa", "a finite pressure (Pa)"),
            (
                config.lowest_pa < config.highest_pa < math.inf,
                "highest_pa",
                f"a finite pressure above lowest_pa = {config.lowest_pa} (Pa)",
            ),
        ),
    )


def reading_noise_std_pa(config: PressureSensorConfig) -> float:
    """The std of a reading's error (Pa): the noise, and the rounding as uniform over one count."""
    return math.sqrt(config.noise_std_pa**2 + config.resolution_pa**2 / 12.0)


def sensor_reading(pressure, standard_normal, config: PressureSensorConfig):
    """The reading of gauge pressure ``pressure`` given a standard normal draw (module docstring).

    Works on Python floats and on symbolic expressions alike.
    """
    symbolic = isinstance(pressure, Expression) or isinstance(standard_normal, Expression)
    # Drake's floor, min and max return Expressions even of floats: floats get Python's.
    round_down, at_least, at_most = (
        (floor, symbolic_max, symbolic_min) if symbolic else (math.floor, max, min)
    )
    noisy = pressure + config.noise_std_pa * standard_normal
    if config.resolution_pa > 0:
        noisy = config.resolution_pa * round_down(noisy / config.resolution_pa + 0.5)
    return at_most(at_least(noisy, config.lowest_pa), config.highest_pa)


def add_pressure_sensor(
    builder: DiagramBuilder,
    name: str,
    config: PressureSensorConfig,
    gauge_pressure: OutputPort,
    period_s: float,
    late: LateRandomSources | None = None,
) -> OutputPort:
    """Adds the sensor reading ``gauge_pressure``; returns its reading's port (Pa).

    .. pydrake_system::

        name: bladder_pressure_sensor
        input_ports:
        - gauge_pressure_pa
        - standard_normal (with noise only)
        output_ports:
        - reading_pa

    Args:
        builder: where the systems go.
        name: the sensor's name; its noise source is ``{name}.noise``.
        config: the sensor.
        gauge_pressure: the bladder's gauge pressure (Pa).
        period_s: how often the noise is drawn (the loop's tick, when the supervisor reads it).
        late: where its RandomSource waits to be added after every other system, if given.
    """
    validate_pressure_sensor(config, name)
    pressure, draw = Variable("gauge_pressure_pa"), Variable("standard_normal")
    noisy = config.noise_std_pa > 0
    inputs = [("gauge_pressure_pa", [pressure])] + ([("standard_normal", [draw])] if noisy else [])
    reading = sensor_reading(Expression(pressure), Expression(draw) if noisy else 0.0, config)
    sensor = add_named_symbolic_system(
        builder, name, inputs=inputs, outputs=[("reading_pa", [reading])]
    )
    builder.Connect(gauge_pressure, sensor.inputs["gauge_pressure_pa"])
    if noisy:
        noise = RandomSource(RandomDistribution.kGaussian, 1, period_s)
        add_random_source(builder, f"{name}.noise", noise, sensor.inputs["standard_normal"], late)
    return sensor.outputs["reading_pa"]
