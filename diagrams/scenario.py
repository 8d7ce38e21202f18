"""A scenario: everything one run of the head positioner needs, as typed dataclasses.

Loaded from the shipped assets and an optional user file with ``yaml_load_typed``, then checked
once, before anything runs. The plant, the controller and each camera are dataclass variants chosen
in YAML by tag, as pydrake's ``yaml_load_typed`` reads ``Union`` fields::

    plant: !IdentifiedPlant {model_file: model_pem_order2.yaml}
    controller: !OffsetFreeLqg {}
    cameras:
      kinect_v3: !KinectV2Config {mount_height_m: 0.95, ...}

The command line's shorthands (``--plant identified:MODEL.yaml``) build the same variants
(``plant_from_shorthand``), and ``shorthand`` writes a variant back as its flag.
"""

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from maskless.analysis.identification.model_file import load_identified_model
from maskless.errors import ConfigError, MasklessError
from maskless.recording import is_sensor_name
from maskless.systems.config_loading import (
    UNSET,
    asset_path,
    check_override,
    find_unset_fields,
    load_config,
)
from maskless.systems.control.offset_free_lqg import OffsetFreeLqgWeights
from maskless.systems.control.pressure_pace_check import lowest_drift_pa
from maskless.systems.control.safety_supervisor import SafetyConfig, validate_safety
from maskless.systems.fault_injection import FaultConfig, validate_faults
from maskless.systems.limits import DURATION_S, IMAGE_RATE_HZ
from maskless.systems.paper_parameters import (
    PaperParameters,
    load_paper_parameters,
    validate_paper_parameters,
)
from maskless.systems.plant.patient_motion import PatientMotionConfig, validate_patient_motion
from maskless.systems.plant.pneumatic_physics import PneumaticParameters
from maskless.systems.plant.pneumatic_plant import (
    load_pneumatic_parameters,
    validate_pneumatic_parameters,
)
from maskless.systems.sensing.camera_error import validate_camera_error
from maskless.systems.sensing.depth_sensor import (
    KinectV1Config,
    KinectV2Config,
    validate_sensor_config,
)
from maskless.systems.sensing.fault_detection import (
    FaultDetectionConfig,
    validate_fault_detection,
)
from maskless.systems.sensing.local_kalman_filter import LocalFilterConfig
from maskless.systems.sensing.pressure_sensor import (
    PressureSensorConfig,
    reading_noise_std_pa,
    validate_pressure_sensor,
)


@dataclass
class PneumaticPlant:
    """The first-principles robot ("the real robot").

    Its constants are the scenario's ``pneumatic`` section.
    """


@dataclass
class PaperPlant:
    """The paper's identified model (Eq. 25-26) behind the paper's valve map.

    Attributes:
        camera: the camera whose distance the model's output is: the paper identified it on the
            fused distance in the Kinect v2 frame (Sec. III-B).
    """

    camera: str = "kinect_v2"


@dataclass
class IdentifiedPlant:
    """A model `maskless identify` wrote, behind the paper's valve map.

    The model's output is the head height.

    Attributes:
        model_file: the model's YAML file.
    """

    model_file: str = ""


@dataclass
class OffsetFreeLqg:
    """The offset-free LQG (settings: the scenario's ``offset_free_lqg`` section).

    Attributes:
        design_model_file: an identified model (a `maskless identify` file) to design on; empty to
            design on the plant itself (the nominal pneumatic plant's linearisation, or the linear
            plant's own model).
    """

    design_model_file: str = ""


@dataclass
class PaperLqg:
    """The paper's LQG (Eq. 27-34), which drives the inlet valve only.

    Attributes:
        camera: the camera whose frame the paper's model (and so its estimator) measures in.
    """

    camera: str = "kinect_v2"


Plant = PneumaticPlant | PaperPlant | IdentifiedPlant
Controller = OffsetFreeLqg | PaperLqg
Camera = KinectV1Config | KinectV2Config

# The command line's shorthands, and the variant each builds; "NAME:FILE" takes a model file.
PLANT_SHORTHANDS = ("pneumatic", "paper", "identified:MODEL.yaml")
CONTROLLER_SHORTHANDS = ("offset-free-lqg", "offset-free-lqg:MODEL.yaml", "paper-lqg")


def plant_from_shorthand(text: str) -> Plant:
    """The plant a ``--plant`` value names.

    Raises:
        ConfigError: naming the value and the shorthands there are.
    """
    name, separator, path = text.partition(":")
    if text == "pneumatic":
        return PneumaticPlant()
    if text == "paper":
        return PaperPlant()
    if name == "identified" and separator and path:
        return IdentifiedPlant(model_file=path)
    raise ConfigError(f"--plant {text!r}: expected one of {', '.join(PLANT_SHORTHANDS)}")


def controller_from_shorthand(text: str) -> Controller:
    """The controller a ``--controller`` value names.

    Raises:
        ConfigError: naming the value and the shorthands there are.
    """
    name, separator, path = text.partition(":")
    if text == "paper-lqg":
        return PaperLqg()
    if name == "offset-free-lqg" and (not separator or path):
        return OffsetFreeLqg(design_model_file=path)
    raise ConfigError(f"--controller {text!r}: expected one of {', '.join(CONTROLLER_SHORTHANDS)}")


def shorthand(choice: Plant | Controller) -> str:
    """The command-line shorthand of a plant or controller (inverse of ``*_from_shorthand``)."""
    match choice:
        case PneumaticPlant():
            return "pneumatic"
        case PaperPlant():
            return "paper"
        case IdentifiedPlant(model_file=path):
            return f"identified:{path}"
        case OffsetFreeLqg(design_model_file=path):
            return f"offset-free-lqg:{path}" if path else "offset-free-lqg"
        case PaperLqg():
            return "paper-lqg"
    raise TypeError(f"not a plant or controller variant: {choice!r}")


def cameras_measured_by(cameras: dict[str, Camera], rendered: bool) -> dict[str, Camera]:
    """``cameras`` with every one rendered (``rendered``) or modelled, the rest as they were."""
    return {
        name: dataclasses.replace(
            camera, rendering=dataclasses.replace(camera.rendering, enabled=rendered)
        )
        for name, camera in cameras.items()
    }


def kind_name(choice: Plant | Controller) -> str:
    """A variant's name without its model file: "pneumatic", "identified", "offset-free-lqg"."""
    return shorthand(choice).partition(":")[0]


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
        tolerance_m: the clinical band (m).
        evaluation_delay_s: tracking is judged from this long after the last reference step to
            the end (s), settled or not.
        estimation_start_s: estimation errors are measured from here on (s), once the filters
            have forgotten their initial guess.
    """

    tolerance_m: float = UNSET
    evaluation_delay_s: float = UNSET
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
            identified model with a noise model (m²), whose innovations form already carries its
            noise; a model without one (a Hammerstein model's) keeps ``weights``'.
    """

    sample_period_s: float = UNSET
    operating_lift_m: float = UNSET
    outlet_full_open_below_m: float = UNSET
    weights: OffsetFreeLqgWeights = field(default_factory=OffsetFreeLqgWeights)
    identified_model_process_noise_m2: float = UNSET


@dataclass
class Scenario:
    """Everything a run needs; defaults from assets/simulation.yaml, pneumatic.yaml and paper.yaml.

    Attributes (besides the sections):
        random_seed: seeds every noise source; the same seed gives the same run, bit for bit.
        duration_s: simulated seconds.
        plant: which plant (a tagged variant: ``!PneumaticPlant``, ``!PaperPlant``,
            ``!IdentifiedPlant``).
        controller: which controller (``!OffsetFreeLqg``, ``!PaperLqg``).
        cameras: camera name -> its model (``!KinectV1Config``, ``!KinectV2Config``); each gets
            its own local Kalman filter, and the fusion fuses them all.
        start_lift_m: where the pneumatic plant's head starts, at rest (m of lift).
        camera_image_rate_hz: images per second each rendered camera adds to the recording.
        patient_motion: the patient's own drift, shifts and breathing, added to the head height.
        faults: name -> a fault injected into a camera, a valve, the controller's ticks or the
            pneumatic plant over a time window (``systems/fault_injection.py``); the
            controller's design never sees them.
        fault_detection: the estimator's checks of each camera and of the fused estimate.
        safety: the supervisor between the controller and the valves, and its limits.
        pressure_sensor: the bladder's gauge pressure sensor the supervisor reads (pneumatic
            plant only).
    """

    random_seed: int = 0
    duration_s: float = UNSET
    plant: Plant = field(default_factory=PneumaticPlant)
    controller: Controller = field(default_factory=OffsetFreeLqg)
    start_lift_m: float = UNSET
    camera_image_rate_hz: float = UNSET
    patient_motion: PatientMotionConfig = field(default_factory=PatientMotionConfig)
    faults: dict[str, FaultConfig] = field(default_factory=dict)
    reference: ReferenceConfig = field(default_factory=ReferenceConfig)
    cameras: dict[str, Camera] = field(default_factory=dict)
    local_filter: LocalFilterConfig = field(default_factory=LocalFilterConfig)
    fault_detection: FaultDetectionConfig = field(default_factory=FaultDetectionConfig)
    safety: SafetyConfig = field(default_factory=SafetyConfig)
    pressure_sensor: PressureSensorConfig = field(default_factory=PressureSensorConfig)
    metrics: MetricsConfig = field(default_factory=MetricsConfig)
    paper: PaperParameters = field(default_factory=PaperParameters)
    pneumatic: PneumaticParameters = field(default_factory=PneumaticParameters)
    offset_free_lqg: OffsetFreeLqgConfig = field(default_factory=OffsetFreeLqgConfig)


def default_scenario() -> Scenario:
    """The shipped defaults, unvalidated: assets/simulation.yaml over the paper's parameters."""
    base = Scenario(paper=load_paper_parameters(), pneumatic=load_pneumatic_parameters())
    return load_config(Scenario, asset_path("simulation.yaml"), defaults=base)


# Drake's RandomGenerator takes a 32-bit seed; larger ones would wrap onto other seeds silently.
MAX_RANDOM_SEED = 2**32 - 1


# Shipped scenario presets are assets/presets/NAME.yaml; population files (population.py) share
# the folder under this prefix.
POPULATION_PRESET_PREFIX = "population_"


def shipped_presets(population: bool = False) -> dict[str, Path]:
    """The shipped presets by name: scenario presets, or population ones (without their prefix)."""
    folder = asset_path("presets/paper_camera_noise.yaml").parent
    return {
        path.stem.removeprefix(POPULATION_PRESET_PREFIX): path
        for path in sorted(folder.glob("*.yaml"))
        if path.stem.startswith(POPULATION_PRESET_PREFIX) == population
    }


def shipped_fault_examples() -> dict[str, Path]:
    """The shipped fault examples by their name under assets/ (``faults/NAME.yaml``)."""
    folder = asset_path("faults/both-cameras-lost.yaml").parent
    return {f"faults/{path.name}": path for path in sorted(folder.glob("*.yaml"))}


def given_or_shipped(path: str | Path) -> Path:
    """``path``, or the shipped example it names when there is no such file here.

    A user who installed the package has the examples (``faults/both-cameras-lost.yaml``) but
    not the folder.
    """
    path = Path(path)
    if path.exists():
        return path
    return shipped_fault_examples().get(path.as_posix(), path)


def scenario_preset_names() -> list[str]:
    """The shipped scenario presets (``--preset NAME``), such as ``paper_camera_noise``."""
    return list(shipped_presets())


def scenario_preset_path(name: str) -> Path:
    """The file of the shipped scenario preset ``name``.

    Raises:
        ConfigError: no scenario preset has that name (the message lists those that do).
    """
    presets = shipped_presets()
    if name not in presets:
        raise ConfigError(f"no scenario preset {name!r}; shipped: {', '.join(presets)}")
    return presets[name]


def with_presets(scenario: Scenario, presets: Sequence[str]) -> Scenario:
    """``scenario`` with the shipped scenario presets ``presets`` applied over it, in order."""
    for name in presets:
        scenario = load_config(Scenario, scenario_preset_path(name), defaults=scenario)
    return scenario


def load_scenario(
    path: str | Path | None = None, *, presets: Sequence[str] = (), **overrides
) -> Scenario:
    """The shipped defaults, then presets, a YAML file and ``overrides``, validated once.

    The YAML file is the one at ``path``.

    Args:
        path: a scenario YAML file, or None for the shipped defaults.
        presets: shipped scenario presets (``scenario_preset_names``) applied before the file.
        **overrides: top-level fields to set after the file (``duration_s=30``,
            ``plant=IdentifiedPlant("m.yaml")``); None leaves a field as configured.

    Raises:
        ConfigError: an unknown or mistyped field, or a value out of range; the message names the
            file (or the overridden fields) and the field, and what was expected.
        MissingFileError: ``path`` does not exist.
    """
    return scenario_with_overrides(path, overrides, labels={}, presets=presets)


def scenario_with_overrides(
    path: str | Path | None,
    overrides: dict[str, object],
    labels: dict[str, str],
    presets: Sequence[str] = (),
) -> Scenario:
    """``load_scenario`` for a caller whose overrides have names of their own.

    Args:
        path: a scenario YAML file, or None for the shipped defaults.
        overrides: field -> value; None leaves the field as configured.
        labels: field -> what the user called it (a command-line flag), for messages.
        presets: shipped scenario presets applied before the file.
    """
    scenario = with_presets(default_scenario(), presets)
    if path is not None:
        path = given_or_shipped(path)
        scenario = load_config(Scenario, path, defaults=scenario)
    given = {name: value for name, value in overrides.items() if value is not None}
    known = set(Scenario.__dataclass_fields__)
    for name, value in given.items():
        if name not in known:
            raise ConfigError(f"unknown scenario field {name!r}; known: {', '.join(sorted(known))}")
        check_override(Scenario, name, value, labels.get(name, "overrides"))
        setattr(scenario, name, value)
    # Validated once, after the overrides: an override may mend what the file set.
    try:
        validate_scenario(scenario)
    except ConfigError as error:
        sources = [f"preset {name}" for name in presets]
        sources += [str(path)] if path is not None else []
        if given:
            names = ", ".join(labels.get(name, name) for name in given)
            sources.append(f"command line ({names})" if labels else f"overrides ({names})")
        raise ConfigError(f"{' with '.join(sources) or 'shipped defaults'}: {error}") from error
    return scenario


def validate_scenario(config: Scenario) -> None:
    """Raises ConfigError naming the first field that is unset or out of range."""
    _validate_camera_names(config)
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
    DURATION_S.check(config.duration_s, "duration_s")
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
    _validate_cameras(config)
    require(
        0 < config.camera_image_rate_hz < math.inf,
        "camera_image_rate_hz",
        config.camera_image_rate_hz,
        "a positive, finite rate",
    )
    IMAGE_RATE_HZ.check(config.camera_image_rate_hz, "camera_image_rate_hz")
    validate_patient_motion(config.patient_motion)
    validate_faults(
        config.faults,
        {name: camera.frame_rate_hz for name, camera in config.cameras.items()},
        kind_name(config.plant),
    )
    validate_fault_detection(config.fault_detection)
    validate_safety(config.safety, config.metrics.tolerance_m)
    validate_pressure_sensor(config.pressure_sensor)
    if config.safety.enabled:
        pace = config.safety.pressure_pace
        lowest = lowest_drift_pa(pace, reading_noise_std_pa(config.pressure_sensor))
        require(
            pace.drift_pa >= lowest,
            "safety.pressure_pace.drift_pa",
            pace.drift_pa,
            f"at least {lowest:.4g} Pa: twice the std of the tracker's residual that the "
            "pressure sensor's noise and rounding alone give (pressure_sensor), or that noise "
            "fills the pace check's sums",
        )
    for field_name in ("initial_position_std_m", "initial_velocity_std_m_s"):
        value = getattr(config.local_filter, field_name)
        require(value > 0, f"local_filter.{field_name}", value, "a positive std")
    metrics = config.metrics
    require(metrics.tolerance_m > 0, "metrics.tolerance_m", metrics.tolerance_m, "> 0")
    for field_name in ("evaluation_delay_s", "estimation_start_s"):
        value = getattr(metrics, field_name)
        require(value >= 0, f"metrics.{field_name}", value, ">= 0")
    validate_paper_parameters(config.paper)
    validate_pneumatic_parameters(config.pneumatic)
    _validate_choices(config)
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
    _validate_run_length(config)
    _validate_reference_reach(config)


def _validate_run_length(config: Scenario) -> None:
    """Refuses a run shorter than one tick of its controller: it would judge nothing it did."""
    tick_s = (
        config.paper.sample_period_s
        if isinstance(config.controller, PaperLqg)
        else config.offset_free_lqg.sample_period_s
    )
    if config.duration_s < tick_s:
        raise ConfigError(
            f"duration_s = {config.duration_s!r}: expected at least one controller tick, "
            f"{tick_s:.6g} s (a shorter run has no command to judge)"
        )


def _validate_reference_reach(config: Scenario) -> None:
    """Refuses a reference the bladder cannot reach, naming ``reference.step_offsets_m``.

    On the pneumatic plant the reference is a lift (start_lift_m plus the offset) within
    [min_lift_m, max_lift_m]. The linear plants start at their model's operating point, somewhere
    in the same bladder's travel, so an offset larger than the whole travel is out of reach.
    """
    pneumatic = config.pneumatic
    travel_m = pneumatic.max_lift_m - pneumatic.min_lift_m
    for offset in config.reference.step_offsets_m:
        if isinstance(config.plant, PneumaticPlant):
            lift = config.start_lift_m + offset
            reachable = pneumatic.min_lift_m <= lift <= pneumatic.max_lift_m
            expected = (
                f"start_lift_m ({config.start_lift_m}) plus each offset within the bladder's "
                f"travel [{pneumatic.min_lift_m}, {pneumatic.max_lift_m}] m"
            )
        else:
            reachable = abs(offset) <= travel_m
            expected = f"offsets within the bladder's whole travel, +-{travel_m:.6g} m"
        if not reachable:
            raise ConfigError(
                f"reference.step_offsets_m = {config.reference.step_offsets_m}: {offset} is out "
                f"of reach; expected {expected}"
            )


# Names the closed loop gives its own systems; a camera's systems are NAME, NAME.noise (rendered:
# NAME.camera, NAME.seed, NAME.frames) and NAME_filter, so a camera may take none of these
# (nor a name starting with "log_").
_LOOP_SYSTEM_NAMES = {
    "reference",
    "fusion",
    "offset_free_lqg",
    "paper_lqg",
    "valve_current_limits",
    "outlet_valve_shut",
    "excitation",
    "scene_graph",
    "head_pose",
    "patient_motion",
    "missed_ticks",
    "pneumatic_plant",
    "paper_plant",
    "identified_plant",
}


def _validate_camera_names(config: Scenario) -> None:
    """Refuses no camera, and a name no topic or system can carry."""
    if not config.cameras:
        raise ConfigError("cameras: expected at least one camera")
    for name in config.cameras:
        # A camera's name is one segment of its recording topics and names its diagram systems.
        if not is_sensor_name(name):
            raise ConfigError(
                f"cameras.{name}: expected a name of ASCII letters, digits and underscores"
            )
        taken = name in _LOOP_SYSTEM_NAMES or name.startswith("log_")
        if taken or name.removesuffix("_filter") in set(config.cameras) - {name}:
            raise ConfigError(f"cameras.{name}: the closed loop has a system of that name already")


def _validate_cameras(config: Scenario) -> None:
    """Refuses a camera that is no camera model, or whose model is out of range."""
    for name, camera in config.cameras.items():
        if not isinstance(camera, Camera.__args__):
            raise ConfigError(
                f"cameras.{name} = {camera!r}: expected a KinectV1Config or a KinectV2Config"
            )
        validate_sensor_config(f"cameras.{name}", camera)
        validate_camera_error(f"cameras.{name}", camera.error)


def _validate_choices(config: Scenario) -> None:
    """Refuses a choice that is no variant, a missing model file, or a camera that is not there."""
    for field_name, choice, variants in (
        ("plant", config.plant, Plant),
        ("controller", config.controller, Controller),
    ):
        if not isinstance(choice, variants.__args__):
            names = ", ".join(variant.__name__ for variant in variants.__args__)
            raise ConfigError(f"{field_name} = {choice!r}: expected one of {names}")
    files = {
        "plant.model_file": getattr(config.plant, "model_file", None),
        "controller.design_model_file": getattr(config.controller, "design_model_file", None),
    }
    if isinstance(config.plant, IdentifiedPlant) and not config.plant.model_file:
        raise ConfigError("plant.model_file: expected the model file of the identified plant")
    for field_name, path in files.items():
        if path and not Path(path).is_file():
            raise ConfigError(f"{field_name} = {path!r}: model file not found")
        if path:
            _check_model_file(field_name, path)
    for field_name, choice in (("plant", config.plant), ("controller", config.controller)):
        camera = getattr(choice, "camera", None)
        if camera is not None and camera not in config.cameras:
            raise ConfigError(
                f"{field_name}.camera = {camera!r}: expected one of the cameras "
                f"({', '.join(config.cameras)})"
            )


def _check_model_file(field_name: str, path: str) -> None:
    """Reads a model file now, so a malformed one is refused before anything runs.

    As the plant, an unstable model is refused too: run open loop, it drives the head to infinity.
    """
    try:
        model = load_identified_model(path)
    except MasklessError as error:
        raise ConfigError(f"{field_name}: {error}") from None
    if field_name == "plant.model_file" and not model.is_stable():
        raise ConfigError(
            f"{field_name} = {path!r}: the model is unstable (largest pole magnitude "
            f"{max(abs(model.poles())):.6g}), so it cannot play the plant"
        )
