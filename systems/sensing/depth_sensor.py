"""Measurement models of the two depth cameras, ``kinect_v1`` and ``kinect_v2``.

``kinect_v1`` is structured light, ``kinect_v2`` time of flight. Both share one port contract: the
true head height above the table in (m); the camera-to-face distance (m) and a validity flag out,
one frame per frame period.

Each frame: the head height from ``latency`` ago becomes a distance below the camera; a warm-up
drift and the published axial noise are added (Kinect v1: Nguyen, Izadi, Lovell 2012; Kinect v2:
Fankhauser et al. 2015); the distance is quantised (v1: 11-bit disparity, v2: depth resolution); a
frame outside the working range or dropped (probability ``dropout_probability``, the zeros in the
authors' logs) reads 0 with ``valid`` = 0, as a Kinect reports invalid pixels.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from statistics import NormalDist
from typing import ClassVar

import numpy as np
from pydrake.common import RandomDistribution
from pydrake.symbolic import (
    Expression,
    MakeVectorVariable,
    Variable,
    exp,
    floor,
    if_then_else,
    logical_and,
    sqrt,
)
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import RandomSource

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.limits import FRAME_RATE_HZ, LATENCY_S, at_least_half_a_frame
from maskless.systems.named_symbolic_system import (
    PortMap,
    SymbolicSystem,
    building_expressions,
    diagram_form,
)
from maskless.systems.sensing.camera_error import CameraErrorConfig
from maskless.systems.symbolic_banks import add_symbolic_banks
from maskless.systems.units import mm_to_m

# Kinect v1 disparity-to-depth model z = 1 / (DISPARITY_SLOPE d + DISPARITY_INTERCEPT), d the 11-bit
# raw disparity (shared/DESIGN.md).
DISPARITY_SLOPE = -0.00307
DISPARITY_INTERCEPT = 3.3309


@dataclass
class CameraRenderingConfig:
    """How a camera is rendered when its measurement comes from images (``rendered_depth_sensor``).

    Colour and depth share one pose and one set of intrinsics (the colour image registered to the
    depth image, as the Kinect SDKs map them), so a pixel means the same place in both.

    Attributes:
        enabled: measure by rendering images and finding the face in them, instead of the
            measurement model's formulas (``--sensors rendered`` sets it for every camera).
        image_width_px: image width (pixels).
        image_height_px: image height (pixels).
        horizontal_fov_deg: horizontal field of view (degrees).
        vertical_fov_deg: vertical field of view (degrees).
        position_m: the camera's [x, y] in the table frame (m), x across the patient, y along the
            patient towards the top of the head; the face's centre is at [0, 0]. The camera looks
            straight down from ``mount_height_m``.
        invalid_pixel_probability: probability that a depth pixel reads 0 (shadowed or unmatched).
        color_scale: the colour image is rendered at this fraction of the camera's resolution:
            the size the face search runs at (the paper downsampled before detecting, Sec.
            III-A), without rendering the pixels it would throw away. Depth keeps the full size.
    """

    enabled: bool = False
    image_width_px: int = UNSET
    image_height_px: int = UNSET
    horizontal_fov_deg: float = UNSET
    vertical_fov_deg: float = UNSET
    position_m: list[float] = UNSET
    invalid_pixel_probability: float = UNSET
    color_scale: float = UNSET


@dataclass
class DepthSensorConfig:
    """What both camera models share. Every field is set in assets/simulation.yaml.

    Attributes:
        mount_height_m: camera height above the table (m).
        frame_rate_hz: frames per second delivered to the filter.
        latency_s: from the head's motion to the frame reaching its filter (s); realised as whole
            frames, at least one (a frame reaches its filter at the filter's next tick).
        dropout_probability: probability that a frame is invalid (reads 0).
        incidence_angle_rad: angle between the camera axis and the face normal (rad).
        min_range_m: nearest valid distance (m).
        max_range_m: farthest valid distance (m).
        warmup_drift_m: range drift at power-on, decaying exponentially (m).
        warmup_time_constant_s: time constant of that decay (s).
        warmup_elapsed_s: how long the camera has been on when the simulation starts (s).
        rendering: whether and how the camera is rendered instead of modelled.
        error: error beyond the per-pixel formulas, added to the measurement
            (``camera_error``); its ``offset_m`` is the offset left after calibration.
    """

    mount_height_m: float = UNSET
    frame_rate_hz: float = UNSET
    latency_s: float = UNSET
    dropout_probability: float = UNSET
    incidence_angle_rad: float = UNSET
    min_range_m: float = UNSET
    max_range_m: float = UNSET
    warmup_drift_m: float = UNSET
    warmup_time_constant_s: float = UNSET
    warmup_elapsed_s: float = UNSET
    rendering: CameraRenderingConfig = field(default_factory=CameraRenderingConfig)
    error: CameraErrorConfig = field(default_factory=CameraErrorConfig)


@dataclass
class KinectV1Config(DepthSensorConfig):
    """Kinect v1 (Xbox 360, structured light); no fields beyond the shared ones."""

    # The camera model, as the paper's parameters name it (its measurement variance sigma_r1^2).
    model: ClassVar[str] = "kinect_v1"


@dataclass
class KinectV2Config(DepthSensorConfig):
    """Kinect v2 (time of flight).

    Attributes:
        resolution_m: depth quantisation step (m).
    """

    model: ClassVar[str] = "kinect_v2"

    resolution_m: float = UNSET


def kinect_v1_noise_std_m(distance_m, incidence_angle_rad=0.0):
    """Axial noise std of Kinect v1 (Nguyen, Izadi, Lovell 2012), m; ``distance_m`` in m."""
    lateral = incidence_angle_rad**2 / (math.pi / 2 - incidence_angle_rad) ** 2
    return 0.0012 + 0.0019 * (distance_m - 0.4) ** 2 + 0.0001 / sqrt_any(distance_m) * lateral


def kinect_v2_noise_std_m(distance_m, incidence_angle_rad=0.0):
    """Axial noise std of Kinect v2 (Fankhauser et al. 2015), m; ``distance_m`` in m."""
    lateral = incidence_angle_rad**2 / (math.pi / 2 - incidence_angle_rad) ** 2
    std_mm = 1.5 - 0.5 * distance_m + 0.3 * distance_m**2 + 0.1 * distance_m**1.5 * lateral
    return mm_to_m(std_mm)


def kinect_v1_quantised_distance_m(distance_m):
    """The distance a Kinect v1 reports: the nearest 11-bit disparity level, back in m."""
    disparity = (1.0 / distance_m - DISPARITY_INTERCEPT) / DISPARITY_SLOPE
    level = floor_any(disparity + 0.5)
    return 1.0 / (DISPARITY_SLOPE * level + DISPARITY_INTERCEPT)


def warmup_drift(config: DepthSensorConfig, time_s):
    """The range drift (m) a camera adds at ``time_s``, decaying since it was switched on.

    ``warmup_drift_m`` exp(-(time_s + warmup_elapsed_s) / warmup_time_constant_s); a float or a
    ``pydrake.symbolic`` expression, as ``time_s`` is.
    """
    elapsed_s = time_s + config.warmup_elapsed_s
    return config.warmup_drift_m * exp_any(-elapsed_s / config.warmup_time_constant_s)


def reported_distance_m(config: DepthSensorConfig, distance_m, standard_normal, time_s):
    """The distance a camera reports for a true one and a standard normal draw.

    The warm-up drift and the model's published axial noise are added, then the distance is
    quantised: Kinect v1 to the nearest 11-bit disparity level, Kinect v2 to its depth resolution.
    Floats, numpy arrays (a depth image, ``depth_image_noise``) and ``pydrake.symbolic`` expressions
    (the measurement model) alike, so both fidelities apply one formula.

    Args:
        config: the camera.
        distance_m: the true camera-to-face distance (m).
        standard_normal: the noise draw (0 for a noise-free camera).
        time_s: the time (s), for the warm-up drift.
    """
    drifted = distance_m + warmup_drift(config, time_s)
    if isinstance(config, KinectV1Config):
        std = kinect_v1_noise_std_m(distance_m, config.incidence_angle_rad)
        return kinect_v1_quantised_distance_m(drifted + std * standard_normal)
    if isinstance(config, KinectV2Config):
        std = kinect_v2_noise_std_m(distance_m, config.incidence_angle_rad)
        noisy = drifted + std * standard_normal
        return config.resolution_m * floor_any(noisy / config.resolution_m + 0.5)
    raise TypeError(f"no camera model for config type {type(config).__name__}")


def exp_any(value):
    """The exponential of a float or a ``pydrake.symbolic`` expression."""
    return exp(value) if isinstance(value, Expression | Variable) else math.exp(value)


def sqrt_any(value):
    """The square root of a float, a numpy array, or a ``pydrake.symbolic`` expression."""
    if isinstance(value, Expression | Variable):
        return sqrt(value)
    return np.sqrt(value) if isinstance(value, np.ndarray) else math.sqrt(value)


def floor_any(value):
    """The floor of a float, a numpy array, or a ``pydrake.symbolic`` expression."""
    if isinstance(value, Expression | Variable):
        return floor(value)
    return np.floor(value) if isinstance(value, np.ndarray) else math.floor(value)


def latency_frames(config: DepthSensorConfig) -> int:
    """The configured latency as whole frames (at least one)."""
    return max(1, math.floor(config.latency_s * config.frame_rate_hz + 0.5))


def validate_sensor_config(name: str, config: DepthSensorConfig) -> None:
    """Raises ConfigError naming the field when a sensor's parameters are out of range."""
    refuse_out_of_range(name, config, _range_checks(config))


def _range_checks(config: DepthSensorConfig):
    """(in range, field, what was expected) for each of a sensor's parameters, in checking order.

    A generator: each check is evaluated only once those before it have passed, so the latency's
    bound is computed from a frame rate already known to be positive.
    """
    yield FRAME_RATE_HZ.contains(config.frame_rate_hz), "frame_rate_hz", FRAME_RATE_HZ.expected()
    in_range, expected = at_least_half_a_frame(config.latency_s, config.frame_rate_hz, "the camera")
    yield in_range, "latency_s", expected
    yield LATENCY_S.contains(config.latency_s), "latency_s", LATENCY_S.expected()
    yield 0.0 <= config.dropout_probability < 1.0, "dropout_probability", "a probability in [0, 1)"
    yield (
        0.0 <= config.incidence_angle_rad < math.pi / 2,
        "incidence_angle_rad",
        "an angle in [0, pi/2)",
    )
    yield (
        0.0 < config.min_range_m < config.max_range_m,
        "min_range_m",
        "0 < min_range_m < max_range_m",
    )
    yield config.mount_height_m > 0, "mount_height_m", "a positive height"
    yield math.isfinite(config.warmup_drift_m), "warmup_drift_m", "a finite drift"
    yield (
        0 < config.warmup_time_constant_s < math.inf,
        "warmup_time_constant_s",
        "a positive, finite time constant",
    )
    yield 0 <= config.warmup_elapsed_s < math.inf, "warmup_elapsed_s", "a finite time >= 0"
    if isinstance(config, KinectV2Config):
        yield config.resolution_m > 0, "resolution_m", "a positive step"
    if config.rendering.enabled:
        yield from _rendering_checks(config.rendering)


def _rendering_checks(rendering: CameraRenderingConfig):
    """(in range, field, what was expected) for a rendered camera's settings."""
    for field_name in ("image_width_px", "image_height_px"):
        size = getattr(rendering, field_name)
        yield (
            16 <= size <= 4096,
            f"rendering.{field_name}",
            "a whole number of pixels in [16, 4096]",
        )
    for field_name in ("horizontal_fov_deg", "vertical_fov_deg"):
        angle = getattr(rendering, field_name)
        yield 0 < angle < 180, f"rendering.{field_name}", "an angle in (0, 180) degrees"
    yield (
        len(rendering.position_m) == 2 and all(map(math.isfinite, rendering.position_m)),
        "rendering.position_m",
        "[x, y], two finite numbers (m)",
    )
    yield (
        0.0 <= rendering.invalid_pixel_probability < 1.0,
        "rendering.invalid_pixel_probability",
        "a probability in [0, 1)",
    )
    yield 0 < rendering.color_scale <= 1, "rendering.color_scale", "a factor in (0, 1]"


def add_depth_sensor(builder: DiagramBuilder, name: str, config: DepthSensorConfig) -> PortMap:
    """Adds a camera model to ``builder``, ``kinect_v1`` or ``kinect_v2`` as ``config`` says.

    ``kinect_v1`` for a KinectV1Config, ``kinect_v2`` for a KinectV2Config.

    .. pydrake_system::

        name: kinect_v1
        input_ports:
        - head_height_m
        output_ports:
        - distance_m
        - valid

    Args:
        builder: where the sensor's systems go.
        name: the sensor's name (and its name in recordings); its noise source is ``{name}.noise``.
        config: the sensor's parameters.

    Noise comes from one Gaussian RandomSource, two draws per frame (the axial noise, and the
    dropout draw compared with the normal quantile of ``dropout_probability``), so a run
    seeded with ``diagram.SetRandomContext`` is reproducible bit for bit. Until the delay line
    has filled (and before the first frame), frames are invalid.
    """
    return add_depth_sensors(builder, {name: config})[name]


def add_depth_sensors(
    builder: DiagramBuilder, configs: Mapping[str, DepthSensorConfig]
) -> dict[str, PortMap]:
    """Adds a camera model per entry of ``configs`` (name -> parameters); returns their ports.

    Each camera is what ``add_depth_sensor`` adds, with its own noise source; cameras of one
    frame rate are one bank (``symbolic_banks.add_symbolic_banks``), which a step costs
    less than a system each. The noise sources are added in the order of ``configs``, so a seed
    draws the same noise either way.
    """
    noises, systems = {}, {}
    for name, config in configs.items():
        validate_sensor_config(name, config)
        period_s = 1.0 / config.frame_rate_hz
        noises[name] = builder.AddNamedSystem(
            f"{name}.noise", RandomSource(RandomDistribution.kGaussian, 2, period_s)
        )
        systems[name] = depth_sensor_system(config, period_s)
    ports = add_symbolic_banks(builder, systems)
    for name, noise in noises.items():
        builder.Connect(noise.get_output_port(), ports[name].inputs.pop("standard_normal"))
    return ports


@building_expressions
def depth_sensor_system(config: DepthSensorConfig, period_s: float) -> SymbolicSystem:
    """The camera model's frames (``add_depth_sensor``) as expressions, its noise an input port.

    Its ports are ``head_height_m`` and ``standard_normal`` (two draws a frame) in, ``distance_m``
    and ``valid`` out; it updates every ``period_s``.
    """
    delay = latency_frames(config) - 1  # the filter's next tick supplies the last frame of latency
    t = Variable("t")
    head_height = Variable("head_height_m")
    normal, dropout_draw = MakeVectorVariable(2, "standard_normal")
    # State: heights seen 1..delay frames ago, then the last frame's distance and validity. Heights
    # are stored as offsets from the camera (h - mount = -distance) so the zero default state is a
    # head at the camera, which only the invalid first frame ever sees.
    history = MakeVectorVariable(delay, "height_history") if delay > 0 else []
    distance_state = Variable("distance_m")
    valid_state = Variable("valid")
    mount = config.mount_height_m
    measured_height = (history[-1] + mount) if delay > 0 else head_height
    true_distance = mount - measured_height

    reported = reported_distance_m(config, true_distance, normal, t)

    in_range = logical_and(true_distance >= config.min_range_m, true_distance <= config.max_range_m)
    if config.dropout_probability > 0:
        # P(draw < Φ⁻¹(p)) = p for a standard normal draw.
        threshold = NormalDist().inv_cdf(config.dropout_probability)
        valid = logical_and(in_range, dropout_draw >= threshold)
    else:
        valid = in_range
    next_history = [head_height - mount] + list(history[:-1]) if delay > 0 else []
    return SymbolicSystem(
        inputs=[
            ("head_height_m", [head_height]),
            ("standard_normal", [normal, dropout_draw]),
        ],
        outputs=[("distance_m", [distance_state]), ("valid", [valid_state])],
        state=list(history) + [distance_state, valid_state],
        dynamics=next_history
        + [
            if_then_else(valid, reported, Expression(0.0)),
            if_then_else(valid, Expression(1.0), Expression(0.0)),
        ],
        time=t,
        time_period=period_s,
    )


make_depth_sensor = diagram_form(add_depth_sensor)
