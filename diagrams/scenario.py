"""The configuration of a closed-loop simulation: dataclasses, loaded from the shipped assets and an
optional user file with ``yaml_load_typed``, then checked before anything runs."""

import math
from dataclasses import dataclass, field
from pathlib import Path

from maskless.errors import ConfigError
from maskless.systems.config_loading import UNSET, asset_path, find_unset_fields, load_config
from maskless.systems.control.offset_free_lqg import OffsetFreeLqgWeights
from maskless.systems.paper_parameters import (
    PaperParameters,
    load_paper_parameters,
    validate_paper_parameters,
)
from maskless.systems.plant.pneumatic_physics import PneumaticParameters
from maskless.systems.plant.pneumatic_plant import (
    load_pneumatic_parameters,
    validate_pneumatic_parameters,
)
from maskless.systems.sensing.depth_sensor import (
    KinectV1Config,
    KinectV2Config,
    validate_sensor_config,
)
from maskless.systems.sensing.local_kalman_filter import LocalFilterConfig

PLANTS = ("pneumatic", "paper", "identified:MODEL.yaml")
CONTROLLERS = ("offset-free-lqg", "offset-free-lqg:MODEL.yaml", "paper-lqg")


@dataclass
class ReferenceConfig:
    """The head-height reference: steps relative to the starting height.

    Attributes:
        step_times_s: when each step happens (s), increasing.
        step_offsets_m: the reference after each step, relative to the start (m).
    """

    step_times_s: list[float] = field(default_factory=list)
    step_offsets_m: list[float] = field(default_factory=list)


@dataclass
class MetricsConfig:
    """How tracking is judged.

    Attributes:
        tolerance_m: the band the head must settle into and stay in (m).
        unsettled_evaluation_delay_s: when the head never settles, errors are measured from this
            long after the last reference step (s).
        estimation_start_s: estimation errors are measured from here on (s), once the filters
            have forgotten their initial guess.
    """

    tolerance_m: float = UNSET
    unsettled_evaluation_delay_s: float = UNSET
    estimation_start_s: float = UNSET


@dataclass
class OffsetFreeLqgConfig:
    """The offset-free LQG controller's design choices.

    Attributes:
        sample_period_s: the controller's period (s).
        operating_lift_m: the pneumatic plant is linearised for design at this lift (m).
        outlet_full_open_below_m: the split-range allocation opens the outlet fully this far below
            the lowest lift the bladder holds with both valves shut (m).
        weights: LQR and Kalman weights.
        identified_model_process_noise_m2: ``weights.process_noise_m2`` for a design on an
            identified model (m²), whose innovations form already carries its noise.
    """

    sample_period_s: float = UNSET
    operating_lift_m: float = UNSET
    outlet_full_open_below_m: float = UNSET
    weights: OffsetFreeLqgWeights = field(default_factory=OffsetFreeLqgWeights)
    identified_model_process_noise_m2: float = UNSET


@dataclass
class SimulationConfig:
    """Everything a closed-loop run needs; defaults from assets/simulation.yaml, pneumatic.yaml
    and paper.yaml.

    Attributes (besides the sections):
        plant: "pneumatic", "paper" or "identified:MODEL.yaml" (a `maskless identify` model file
            whose output is the head height).
        controller: "offset-free-lqg" (designed on the plant's linearisation or model),
            "offset-free-lqg:MODEL.yaml" (designed on an identified model) or "paper-lqg".
        start_lift_m: where the pneumatic plant's head starts, at rest (m of lift).
    """

    random_seed: int = 0
    duration_s: float = UNSET
    plant: str = "pneumatic"
    controller: str = "offset-free-lqg"
    start_lift_m: float = UNSET
    reference: ReferenceConfig = field(default_factory=ReferenceConfig)
    kinect_v1: KinectV1Config = field(default_factory=KinectV1Config)
    kinect_v2: KinectV2Config = field(default_factory=KinectV2Config)
    local_filter: LocalFilterConfig = field(default_factory=LocalFilterConfig)
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    paper: PaperParameters = field(default_factory=PaperParameters)
    pneumatic: PneumaticParameters = field(default_factory=PneumaticParameters)
    offset_free_lqg: OffsetFreeLqgConfig = field(default_factory=OffsetFreeLqgConfig)

    def sensors(self) -> dict:
        """The camera configs by name, in a fixed order."""
        return {"kinect_v1": self.kinect_v1, "kinect_v2": self.kinect_v2}


def default_config() -> SimulationConfig:
    """The shipped defaults: assets/simulation.yaml over the paper's parameters."""
    base = SimulationConfig(paper=load_paper_parameters(), pneumatic=load_pneumatic_parameters())
    return load_config(SimulationConfig, asset_path("simulation.yaml"), defaults=base)


def load_simulation_config(path: str | Path | None = None) -> SimulationConfig:
    """The shipped defaults, overridden by the YAML file at ``path`` when given, then validated.

    Raises:
        ConfigError: an unknown or mistyped field, or a value out of range; the message names the
            file (or the field) and what was expected.
    """
    return load_config_with_overrides(path, {})


# Drake's RandomGenerator takes a 32-bit seed; larger ones would wrap onto other seeds silently.
MAX_RANDOM_SEED = 2**32 - 1


def load_config_with_overrides(
    path: str | Path | None, overrides: dict[str, tuple[str, object]]
) -> SimulationConfig:
    """``load_simulation_config(path)`` with fields set from the command line, then validated.

    Args:
        path: the --config file, or None for the shipped defaults.
        overrides: flag -> (field, value); a value of None leaves the field as configured.

    Raises:
        ConfigError: naming the file, or the flags, and the field that is out of range.
    """
    config = default_config()
    if path is not None:
        config = load_config(SimulationConfig, path, defaults=config)
    for field_name, value in overrides.values():
        if value is not None:
            setattr(config, field_name, value)
    # Validated once, after the flags: a flag may mend what the file set.
    try:
        validate_simulation_config(config)
    except ConfigError as error:
        sources = [str(path)] if path is not None else []
        if overrides:
            sources.append(f"command line ({'/'.join(overrides)})")
        raise ConfigError(f"{' with '.join(sources) or 'shipped defaults'}: {error}") from error
    return config


def validate_simulation_config(config: SimulationConfig) -> None:
    """Raises ConfigError naming the first field that is unset or out of range."""
    unset = find_unset_fields(config)
    if unset:
        raise ConfigError(f"fields not set: {', '.join(unset)}")

    def require(condition, field_name, value, expected):
        if not condition:
            raise ConfigError(f"{field_name} = {value}: expected {expected}")

    require(
        0 <= config.random_seed <= MAX_RANDOM_SEED,
        "random_seed",
        config.random_seed,
        f"an integer in [0, {MAX_RANDOM_SEED}]",
    )
    require(
        math.isfinite(config.duration_s) and config.duration_s > 0,
        "duration_s",
        config.duration_s,
        "a positive, finite duration",
    )
    reference = config.reference
    if len(reference.step_times_s) != len(reference.step_offsets_m):
        raise ConfigError(
            f"reference: step_times_s has {len(reference.step_times_s)} entries but "
            f"step_offsets_m has {len(reference.step_offsets_m)}; expected one offset per time"
        )
    times = reference.step_times_s
    require(
        all(t > 0 for t in times) and all(b > a for a, b in zip(times, times[1:], strict=False)),
        "reference.step_times_s",
        times,
        "positive, increasing times",
    )
    for name, sensor in config.sensors().items():
        validate_sensor_config(name, sensor)
    for field_name in ("initial_position_std_m", "initial_velocity_std_m_s"):
        value = getattr(config.local_filter, field_name)
        require(value > 0, f"local_filter.{field_name}", value, "a positive std")
    metrics = config.metrics
    require(metrics.tolerance_m > 0, "metrics.tolerance_m", metrics.tolerance_m, "> 0")
    for field_name in ("unsettled_evaluation_delay_s", "estimation_start_s"):
        value = getattr(metrics, field_name)
        require(value >= 0, f"metrics.{field_name}", value, ">= 0")
    validate_paper_parameters(config.paper)
    validate_pneumatic_parameters(config.pneumatic)
    _validate_choice("plant", config.plant, PLANTS)
    _validate_choice("controller", config.controller, CONTROLLERS)
    controller = config.offset_free_lqg
    require(
        controller.sample_period_s > 0,
        "offset_free_lqg.sample_period_s",
        controller.sample_period_s,
        "> 0",
    )
    require(
        controller.outlet_full_open_below_m > 0,
        "offset_free_lqg.outlet_full_open_below_m",
        controller.outlet_full_open_below_m,
        "> 0",
    )
    for field_name in (
        "output_error_weight_per_m2",
        "command_weight_per_m2",
        "process_noise_m2",
        "disturbance_noise_m2",
        "measurement_noise_m2",
    ):
        value = getattr(controller.weights, field_name)
        require(value > 0, f"offset_free_lqg.weights.{field_name}", value, "> 0")
    fraction = controller.weights.state_weight_fraction
    require(fraction >= 0, "offset_free_lqg.weights.state_weight_fraction", fraction, ">= 0")
    require(
        controller.identified_model_process_noise_m2 >= 0,
        "offset_free_lqg.identified_model_process_noise_m2",
        controller.identified_model_process_noise_m2,
        ">= 0",
    )
    pneumatic = config.pneumatic
    lifts = {
        "start_lift_m": config.start_lift_m,
        "offset_free_lqg.operating_lift_m": controller.operating_lift_m,
    }
    for field_name, value in lifts.items():
        require(
            pneumatic.min_lift_m <= value <= pneumatic.max_lift_m,
            field_name,
            value,
            f"a lift within the bladder's travel [{pneumatic.min_lift_m}, {pneumatic.max_lift_m}]",
        )


def model_file_of(choice: str) -> Path | None:
    """The model file named by a plant or controller choice ("name:FILE"), if any."""
    _, separator, path = choice.partition(":")
    return Path(path) if separator else None


def _validate_choice(field_name: str, value: str, allowed: tuple[str, ...]) -> None:
    """Refuses a choice that is not one of ``allowed`` ("name:MODEL.yaml" takes any file that
    exists)."""
    name, separator, path = value.partition(":")
    forms = {choice.partition(":")[0] + (":" if ":" in choice else "") for choice in allowed}
    if name + separator not in forms or (separator and not path):
        raise ConfigError(f"{field_name} = {value!r}: expected one of {', '.join(allowed)}")
    if separator and not Path(path).is_file():
        raise ConfigError(f"{field_name} = {value!r}: model file not found: {path}")
