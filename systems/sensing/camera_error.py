"""Camera error beyond the per-pixel formulas, added to a camera's measurement.

The published noise models give one pixel's noise; a camera's measurement of a face also carries
error that does not average away: what the paper measured (22.7 / 11.5 mm² for its Kinect v1 / v2,
Sec. III, Fig. 1, 7-9x the formulas), error that persists from frame to frame, and an offset left
by calibration. Each frame's measurement, when valid, gets:

- a residual calibration offset, ``offset_m``;
- white noise of std ``white_noise_std_m`` (``assets/presets/paper_camera_noise.yaml`` sets it so
  the measurement's variance is the paper's);
- a first-order Gauss-Markov error of std ``correlated_std_m`` and correlation time
  ``correlation_time_s``: e+ = a e + sqrt(1 - a²) std n, a = exp(-T / correlation_time_s), so its
  variance is std² and its autocorrelation exp(-lag / correlation_time_s).

The Gauss-Markov error starts at 0 and reaches its variance within a few correlation times. An
invalid frame stays 0 and invalid. The system sits between a camera (modelled or rendered) and
its local filter, so both fidelities take it alike.
"""

import math
from dataclasses import dataclass

from pydrake.common import RandomDistribution
from pydrake.symbolic import Expression, MakeVectorVariable, Variable, if_then_else
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import RandomSource

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.late_random_sources import LateRandomSources, add_random_source
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
)


@dataclass
class CameraErrorConfig:
    """A camera's error beyond the per-pixel formulas; a section not ``enabled`` needs nothing.

    Attributes:
        enabled: add the error.
        offset_m: residual calibration offset (m).
        white_noise_std_m: std of independent noise per frame (m).
        correlated_std_m: std of the Gauss-Markov error (m).
        correlation_time_s: its correlation time (s).
    """

    enabled: bool = False
    offset_m: float = UNSET
    white_noise_std_m: float = UNSET
    correlated_std_m: float = UNSET
    correlation_time_s: float = UNSET


def validate_camera_error(name: str, config: CameraErrorConfig) -> None:
    """Raises ConfigError naming ``{name}.error.FIELD`` when a value is out of range."""
    if not config.enabled:
        return
    checks = [
        (math.isfinite(config.offset_m), "offset_m", "a finite offset"),
        (0 <= config.white_noise_std_m < math.inf, "white_noise_std_m", "a finite std >= 0"),
        (0 <= config.correlated_std_m < math.inf, "correlated_std_m", "a finite std >= 0"),
        (0 < config.correlation_time_s < math.inf, "correlation_time_s", "a positive time"),
    ]
    refuse_out_of_range(f"{name}.error", config, checks)


def add_camera_error(
    builder: DiagramBuilder,
    name: str,
    config: CameraErrorConfig,
    camera: PortMap,
    frame_period_s: float,
    late: LateRandomSources | None = None,
) -> PortMap:
    """Adds ``config``'s error to ``camera``'s measurement; returns the ports the filter reads.

    With ``enabled`` false, returns ``camera`` itself and adds nothing.

    .. pydrake_system::

        name: kinect_v1.error
        input_ports:
        - distance_m
        - valid
        output_ports:
        - distance_m
        - valid

    Args:
        builder: where the systems go.
        name: the camera's name; the systems are ``{name}.error`` and ``{name}.error.noise``.
        config: the error.
        camera: the camera's ports (``distance_m``, ``valid``).
        frame_period_s: the camera's frame period (s), the error's update period.
        late: where its RandomSource waits to be added after every other system, if given.
    """
    if not config.enabled:
        return camera
    validate_camera_error(name, config)
    error = _add_error_dynamics(builder, f"{name}.error", config, frame_period_s)
    noise = RandomSource(RandomDistribution.kGaussian, 2, frame_period_s)
    add_random_source(builder, f"{name}.error.noise", noise, error.inputs["standard_normal"], late)
    for port in ("distance_m", "valid"):
        builder.Connect(camera.outputs[port], error.inputs[port])
    return PortMap(outputs={port: error.outputs[port] for port in ("distance_m", "valid")})


@building_expressions
def _add_error_dynamics(
    builder: DiagramBuilder, name: str, config: CameraErrorConfig, frame_period_s: float
) -> PortMap:
    distance, valid = Variable("distance_m"), Variable("valid")
    white, innovation = MakeVectorVariable(2, "standard_normal")
    correlated = Variable("correlated_error_m")
    decay = math.exp(-frame_period_s / config.correlation_time_s)
    error = config.offset_m + correlated + config.white_noise_std_m * white
    is_valid = valid > 0.5
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[
            ("distance_m", [distance]),
            ("valid", [valid]),
            ("standard_normal", [white, innovation]),
        ],
        outputs=[
            ("distance_m", [if_then_else(is_valid, distance + error, Expression(0.0))]),
            ("valid", [valid]),
        ],
        state=[correlated],
        dynamics=[
            decay * correlated + math.sqrt(1 - decay**2) * config.correlated_std_m * innovation
        ],
        time_period=frame_period_s,
    )
