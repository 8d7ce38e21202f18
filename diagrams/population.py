"""A population of patients for the Monte Carlo: what each trial draws, and from what.

A population file (``assets/presets/population_*.yaml``, or the user's own) holds the sweep's
settings, the distributions a patient is drawn from, and the scenario every trial runs (its
``scenario`` section overrides the shipped defaults, as ``maskless simulate --config`` does).

Each trial draws one patient: a head mass, the bladder's stiffness and leak, both valves'
conductances and the supply pressure (each uniform between its low and high; a factor multiplies
the scenario's nominal value), and a reference, as a treatment plan would ask of this patient:
the head is first positioned at a drawn lift, then stepped by a drawn size, up or down. Both
levels lie inside the patient's working range (``lift_window_m``: ``lift_margin_m`` above where
the head rests with both valves shut, and no higher than where the inlet holds it at
``inlet_authority_fraction`` of its span). A step wider than that range (a heavy head on a weak
supply) is drawn all the same and runs past it; whether each controller's valves can hold both
levels at all is reported with the metrics (``patient_reach``). The controller is designed on the
nominal plant, and its design, state and parameters do not depend on the draw; what it receives
of the patient is the reference, chosen as a planner who knows the patient's range would choose
it.

Trial k's draws come from ``SeedSequence([seed, k])`` alone, so a trial gives the same patient and
noise whichever worker runs it, in whatever order, and a sweep that grows or resumes redraws none.
A patient may be run with several noise seeds (``seeds_per_patient``): run r's seed is child r of
the trial's noise sequence, so adding seeds changes none of those drawn before.
"""

import dataclasses
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from maskless.diagrams.scenario import (
    PneumaticPlant,
    Scenario,
    controller_from_shorthand,
    default_scenario,
    shipped_presets,
    validate_scenario,
    with_presets,
)
from maskless.errors import ConfigError, MissingFileError
from maskless.systems.config_loading import UNSET, load_config, refuse_out_of_range
from maskless.systems.plant.pneumatic_physics import LIFT, PneumaticParameters
from maskless.systems.plant.pneumatic_plant import (
    equilibrium_state,
    steady_gauge_pressure_pa,
    steady_lift_m,
)


@dataclass
class UniformRange:
    """A quantity drawn uniformly between ``low`` and ``high`` (equal: not drawn at all)."""

    low: float = UNSET
    high: float = UNSET

    def draw(self, rng: np.random.Generator) -> float:
        """One draw; a fixed value (low == high) still consumes one, so later draws keep theirs."""
        return float(rng.uniform(self.low, self.high))


@dataclass
class PopulationConfig:
    """The distributions a patient is drawn from.

    Attributes:
        head_mass_kg: the head's mass (kg).
        stiffness_factor: times the scenario's ``pneumatic.stiffness_n_m``.
        leak_factor: times its ``pneumatic.leak_sonic_conductance_m3_s_pa``.
        inlet_conductance_factor: times its ``pneumatic.inlet.sonic_conductance_m3_s_pa``.
        outlet_conductance_factor: times its ``pneumatic.outlet.sonic_conductance_m3_s_pa``.
        supply_gauge_pressure_pa: the compressor's regulated supply (Pa, gauge).
        step_size_m: the size of the judged step (m); up or down with equal chance.
        lift_margin_m: both reference levels lie at least this far above where the patient's
            head rests with both valves shut (m; below zero lift for a heavy head).
        inlet_authority_fraction: ...and no higher than where the patient's inlet holds it at
            this fraction of its current span.
    """

    head_mass_kg: UniformRange = field(default_factory=UniformRange)
    stiffness_factor: UniformRange = field(default_factory=UniformRange)
    leak_factor: UniformRange = field(default_factory=UniformRange)
    inlet_conductance_factor: UniformRange = field(default_factory=UniformRange)
    outlet_conductance_factor: UniformRange = field(default_factory=UniformRange)
    supply_gauge_pressure_pa: UniformRange = field(default_factory=UniformRange)
    step_size_m: UniformRange = field(default_factory=UniformRange)
    lift_margin_m: float = UNSET
    inlet_authority_fraction: float = UNSET


@dataclass
class MonteCarloConfig:
    """A sweep: how many trials, which controllers, the population and the scenario.

    Attributes:
        trials: patients drawn (``--trials`` overrides); each runs once per controller and seed.
        seeds_per_patient: runs of each patient with different noise (camera noise, motion),
            the same plant and reference.
        seed: the population's seed; trial k draws from ``SeedSequence([seed, k])``.
        controllers: each trial runs with each of these (``--controller`` shorthands:
            ``offset-free-lqg``, ``paper-lqg``, ``offset-free-lqg:MODEL.yaml``).
        positioning_time_s: when the reference moves the head to the drawn starting lift (s).
        step_time_s: when the judged step happens (s); tracking is judged from
            ``scenario.metrics.evaluation_delay_s`` after it to ``scenario.duration_s``.
        worst_traces: how many of each controller's worst trials (by p95 error) the plot shows.
        scenario_presets: shipped scenario presets (``assets/presets/NAME.yaml``, such as
            ``paper_camera_noise``) applied in order over the shipped defaults, under
            ``scenario``.
        population: the distributions.
        scenario: what every trial runs, over the shipped defaults and ``scenario_presets``; its
            reference is the sweep's (set per trial), its plant must be the pneumatic one.
    """

    trials: int = 0
    seeds_per_patient: int = 1
    seed: int = 0
    controllers: list[str] = field(default_factory=list)
    positioning_time_s: float = UNSET
    step_time_s: float = UNSET
    worst_traces: int = 5
    scenario_presets: list[str] = field(default_factory=list)
    population: PopulationConfig = field(default_factory=PopulationConfig)
    scenario: Scenario = field(default_factory=Scenario)


def preset_names() -> list[str]:
    """The shipped population presets (``--preset NAME``)."""
    return list(shipped_presets(population=True))


def population_preset_path(name: str) -> Path:
    """The file of the shipped population preset ``name``.

    Raises:
        ConfigError: no preset has that name (the message lists those that do).
    """
    presets = shipped_presets(population=True)
    if name not in presets:
        raise ConfigError(f"no population preset {name!r}; shipped: {', '.join(presets)}")
    return presets[name]


def load_population(path: str | Path) -> MonteCarloConfig:
    """A population file over the shipped scenario defaults, validated.

    Raises:
        ConfigError: an unknown, mistyped or out-of-range field (named with the file).
        MissingFileError: ``path`` does not exist.
    """
    path = Path(path)
    if not path.is_file():
        raise MissingFileError(f"population file not found: {path}")
    # Read once for the presets its scenario builds on, then again over them.
    config = load_config(
        MonteCarloConfig, path, defaults=MonteCarloConfig(scenario=default_scenario())
    )
    try:
        if config.scenario_presets:
            try:
                scenario = with_presets(default_scenario(), config.scenario_presets)
            except ConfigError as error:
                raise ConfigError(f"scenario_presets: {error}") from error
            config = load_config(
                MonteCarloConfig, path, defaults=MonteCarloConfig(scenario=scenario)
            )
        config.controllers = [_model_file_resolved(c, path.parent) for c in config.controllers]
        validate_population(config)
    except ConfigError as error:
        raise ConfigError(f"{path}: {error}") from error
    return config


def validate_population(config: MonteCarloConfig) -> None:
    """Raises ConfigError naming the first field that is unset or out of range."""
    refuse_out_of_range("", config, _sweep_checks(config))
    validate_scenario(sweep_scenario(config, levels_m=(0.0, 0.0)))
    if not isinstance(config.scenario.plant, PneumaticPlant):
        raise ConfigError(
            "scenario.plant: expected !PneumaticPlant (the population draws its heads)"
        )
    for name in config.controllers:
        try:
            controller_from_shorthand(name)
        except ConfigError as error:
            raise ConfigError(f"controllers: {error}") from error
        _, _, model_file = name.partition(":")
        if model_file and not Path(model_file).is_file():
            raise MissingFileError(f"controllers: {name}: model file not found")
    for name, draw in _ranges(config.population):
        refuse_out_of_range(
            f"population.{name}",
            draw,
            [(0 < draw.low <= draw.high, "low", f"0 < low <= high ({draw.high})")],
        )
    refuse_out_of_range("population", config.population, _window_checks(config))


def _window_checks(config: MonteCarloConfig):
    """(in range, field, expected) for the reference's working range, lazily."""
    population = config.population
    yield population.lift_margin_m >= 0, "lift_margin_m", "a margin >= 0"
    yield (
        0 < population.inlet_authority_fraction <= 1,
        "inlet_authority_fraction",
        "a fraction in (0, 1]",
    )
    low, high = lift_window_m(config.scenario.pneumatic, population)
    yield (
        high - low >= population.step_size_m.high,
        "step_size_m.high",
        f"a step that fits the nominal plant's working range, {low * 1e3:.2f} to "
        f"{high * 1e3:.2f} mm of lift (lift_margin_m and inlet_authority_fraction set it)",
    )


def _model_file_resolved(controller: str, folder: Path) -> str:
    """``controller`` with its model file (if any) relative to ``folder``, the population's."""
    name, separator, model_file = controller.partition(":")
    if not model_file or Path(model_file).is_absolute():
        return controller
    return f"{name}{separator}{folder / model_file}"


def _sweep_checks(config: MonteCarloConfig):
    """(in range, field, expected) for the sweep's own settings (lazily, in order)."""
    yield config.trials >= 1, "trials", "at least 1 trial"
    yield config.seeds_per_patient >= 1, "seeds_per_patient", "at least 1 seed"
    yield 0 <= config.seed < 2**32, "seed", "a seed in [0, 2^32)"
    yield len(config.controllers) > 0, "controllers", "at least one controller"
    yield (
        len(set(config.controllers)) == len(config.controllers),
        "controllers",
        "no controller twice",
    )
    yield config.positioning_time_s >= 0, "positioning_time_s", "a time >= 0"
    yield config.step_time_s > config.positioning_time_s, "step_time_s", "after positioning_time_s"
    window_start_s = config.step_time_s + config.scenario.metrics.evaluation_delay_s
    yield (
        window_start_s < config.scenario.duration_s,
        "step_time_s",
        f"a step judged before the run ends: step_time_s + evaluation delay ({window_start_s} s) "
        f"< scenario.duration_s ({config.scenario.duration_s} s)",
    )
    yield config.worst_traces >= 0, "worst_traces", "a count >= 0"


def _ranges(population: PopulationConfig):
    """(name, UniformRange) of each drawn quantity."""
    fields = ((f.name, getattr(population, f.name)) for f in dataclasses.fields(population))
    return [(name, value) for name, value in fields if isinstance(value, UniformRange)]


def sweep_scenario(config: MonteCarloConfig, levels_m, seed: int | None = None) -> Scenario:
    """The scenario a trial runs: the population's, its reference the sweep's two steps.

    ``levels_m`` are the reference's two offsets from the start (positioned, then stepped); a
    built loop's levels are rewritten per trial (``Patient.reference_levels_m``), so any two
    values build the same Diagram.
    """
    return dataclasses.replace(
        config.scenario,
        random_seed=config.scenario.random_seed if seed is None else seed,
        reference=dataclasses.replace(
            config.scenario.reference,
            step_times_s=[config.positioning_time_s, config.step_time_s],
            step_offsets_m=list(levels_m),
        ),
    )


@dataclass(frozen=True)
class Patient:
    """One trial's draws.

    Attributes:
        trial: the trial's index: which patient.
        run: which of the patient's ``seeds_per_patient`` runs.
        seed: the simulation's seed (every noise source of the run).
        head_mass_kg, stiffness_n_m, leak_sonic_conductance_m3_s_pa,
        inlet_sonic_conductance_m3_s_pa, outlet_sonic_conductance_m3_s_pa,
        supply_gauge_pressure_pa: the drawn plant.
        positioned_lift_m: the lift the head is first brought to: m above the rest height, where
            the nominal head rests on the empty bladder.
        step_m: the judged step, signed (m).
    """

    trial: int
    run: int
    seed: int
    head_mass_kg: float
    stiffness_n_m: float
    leak_sonic_conductance_m3_s_pa: float
    inlet_sonic_conductance_m3_s_pa: float
    outlet_sonic_conductance_m3_s_pa: float
    supply_gauge_pressure_pa: float
    positioned_lift_m: float
    step_m: float

    def reference_levels_m(self, start_height_m: float, rest_height_m: float) -> list[float]:
        """The reference's levels: the start height, positioned, then stepped (m above the table).

        Args:
            start_height_m: where the loop starts (``ClosedLoop.start_height_m``).
            rest_height_m: the plant's ``rest_head_height_m``.
        """
        positioned = rest_height_m + self.positioned_lift_m
        return [start_height_m, positioned, positioned + self.step_m]


def lift_window_m(p: PneumaticParameters, population: PopulationConfig) -> tuple[float, float]:
    """The lifts a reference may ask of plant ``p``: (lowest, highest), m above its rest height.

    Lowest: ``lift_margin_m`` above where the head rests with both valves shut. Highest: where the
    inlet holds it at ``inlet_authority_fraction`` of its current span, the outlet shut.
    """
    shut = steady_lift_m(p, steady_gauge_pressure_pa(p, 0.0, 0.0))
    top_current = p.inlet.starting_current_a + (
        population.inlet_authority_fraction * p.inlet.current_span_a
    )
    return shut + population.lift_margin_m, float(equilibrium_state(p, top_current, 0.0)[LIFT])


def draw_patient(config: MonteCarloConfig, trial: int, run: int = 0) -> Patient:
    """Trial ``trial``'s patient (its ``run``-th seed): the plant, and a reference in its range."""
    draws, noises = np.random.SeedSequence([config.seed, trial]).spawn(2)
    noise = noises.spawn(run + 1)[run]
    rng = np.random.default_rng(draws)
    population, p = config.population, config.scenario.pneumatic
    plant = {
        "head_mass_kg": population.head_mass_kg.draw(rng),
        "stiffness_n_m": population.stiffness_factor.draw(rng) * p.stiffness_n_m,
        "leak_sonic_conductance_m3_s_pa": population.leak_factor.draw(rng)
        * p.leak_sonic_conductance_m3_s_pa,
        "inlet_sonic_conductance_m3_s_pa": population.inlet_conductance_factor.draw(rng)
        * p.inlet.sonic_conductance_m3_s_pa,
        "outlet_sonic_conductance_m3_s_pa": population.outlet_conductance_factor.draw(rng)
        * p.outlet.sonic_conductance_m3_s_pa,
        "supply_gauge_pressure_pa": population.supply_gauge_pressure_pa.draw(rng),
    }
    step = population.step_size_m.draw(rng) * rng.choice([-1.0, 1.0])
    unplaced = Patient(
        trial,
        run,
        int(noise.generate_state(1)[0]),
        **plant,
        positioned_lift_m=0.0,
        step_m=float(step),
    )
    low, high = lift_window_m(patient_plant(p, unplaced), population)
    lowest, highest = max(low, low - step), min(high, high - step)
    # A step wider than the range starts from the range's far end and runs past the other.
    positioned = rng.uniform(lowest, highest) if lowest <= highest else (low if step > 0 else high)
    return dataclasses.replace(unplaced, positioned_lift_m=float(positioned))


def patient_plant(nominal: PneumaticParameters, patient: Patient) -> PneumaticParameters:
    """The nominal plant with the patient's drawn constants."""
    return dataclasses.replace(
        nominal,
        head_mass_kg=patient.head_mass_kg,
        stiffness_n_m=patient.stiffness_n_m,
        leak_sonic_conductance_m3_s_pa=patient.leak_sonic_conductance_m3_s_pa,
        supply_gauge_pressure_pa=patient.supply_gauge_pressure_pa,
        inlet=dataclasses.replace(
            nominal.inlet, sonic_conductance_m3_s_pa=patient.inlet_sonic_conductance_m3_s_pa
        ),
        outlet=dataclasses.replace(
            nominal.outlet, sonic_conductance_m3_s_pa=patient.outlet_sonic_conductance_m3_s_pa
        ),
    )


def patient_reach(
    nominal: PneumaticParameters, patient: Patient, outlet_used: bool = True
) -> tuple[float, float]:
    """The lifts the drawn plant holds at rest: (lowest, highest), m above its rest height.

    Highest with the inlet fully open and the outlet shut; lowest with the outlet fully open and
    the inlet shut, or with both shut for a controller that never opens the outlet (the paper's).
    """
    p = patient_plant(nominal, patient)
    lowest = steady_lift_m(p, steady_gauge_pressure_pa(p, 0.0, 1.0 if outlet_used else 0.0))
    highest = steady_lift_m(p, steady_gauge_pressure_pa(p, 1.0, 0.0))
    return lowest, highest
