"""The configuration of a closed-loop simulation: dataclasses, loaded from the shipped assets and an
optional user file with ``yaml_load_typed``, then checked before anything runs."""

from dataclasses import dataclass, field
from pathlib import Path

from maskless.assets.loader import UNSET, ConfigError, asset_path, find_unset_fields, load_config
from maskless.systems.depth_sensor import KinectV1Config, KinectV2Config, validate_sensor_config
from maskless.systems.local_kalman_filter import LocalFilterConfig
from maskless.systems.paper_parameters import PaperParameters, load_paper_parameters


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
class SimulationConfig:
    """Everything a closed-loop run needs; defaults from assets/simulation.yaml and paper.yaml."""

    random_seed: int = 0
    duration_s: float = UNSET
    reference: ReferenceConfig = field(default_factory=ReferenceConfig)
    kinect_v1: KinectV1Config = field(default_factory=KinectV1Config)
    kinect_v2: KinectV2Config = field(default_factory=KinectV2Config)
    local_filter: LocalFilterConfig = field(default_factory=LocalFilterConfig)
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    paper: PaperParameters = field(default_factory=PaperParameters)

    def sensors(self) -> dict:
        """The camera configs by name, in a fixed order."""
        return {"kinect_v1": self.kinect_v1, "kinect_v2": self.kinect_v2}


def default_config() -> SimulationConfig:
    """The shipped defaults: assets/simulation.yaml over the paper's parameters."""
    base = SimulationConfig(paper=load_paper_parameters())
    return load_config(SimulationConfig, asset_path("simulation.yaml"), defaults=base)


def load_simulation_config(path: str | Path | None = None) -> SimulationConfig:
    """The shipped defaults, overridden by the YAML file at ``path`` when given, then validated.

    Raises:
        ConfigError: an unknown or mistyped field, or a value out of range; the message names the
            file (or the field) and what was expected.
    """
    config = default_config()
    if path is not None:
        config = load_config(SimulationConfig, path, defaults=config)
    try:
        validate_simulation_config(config)
    except ConfigError as error:
        where = str(path) if path is not None else "shipped defaults"
        raise ConfigError(f"{where}: {error}") from error
    return config


def validate_simulation_config(config: SimulationConfig) -> None:
    """Raises ConfigError naming the first field that is unset or out of range."""
    unset = find_unset_fields(config)
    if unset:
        raise ConfigError(f"fields not set: {', '.join(unset)}")
    if not config.duration_s > 0:
        raise ConfigError(f"duration_s = {config.duration_s}: expected a positive duration")
    reference = config.reference
    if len(reference.step_times_s) != len(reference.step_offsets_m):
        raise ConfigError(
            f"reference: step_times_s has {len(reference.step_times_s)} entries but "
            f"step_offsets_m has {len(reference.step_offsets_m)}; expected one offset per time"
        )
    times = reference.step_times_s
    if any(t <= 0 for t in times) or any(b <= a for a, b in zip(times, times[1:], strict=False)):
        raise ConfigError(f"reference.step_times_s = {times}: expected positive, increasing times")
    for name, sensor in config.sensors().items():
        validate_sensor_config(name, sensor)
    if not config.metrics.tolerance_m > 0:
        raise ConfigError(f"metrics.tolerance_m = {config.metrics.tolerance_m}: expected > 0")
