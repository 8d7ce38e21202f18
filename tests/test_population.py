"""Populations: files and presets refused or loaded, draws per trial and their distributions."""

import dataclasses

import pytest
from scipy import stats

from maskless.diagrams.population import (
    Patient,
    draw_patient,
    load_population,
    nominal_lift_window_m,
    patient_plant,
    patient_reach,
    population_preset_path,
    preset_names,
    sweep_scenario,
)
from maskless.diagrams.scenario import load_scenario
from maskless.errors import ConfigError, MissingFileError
from maskless.systems.config_loading import asset_path
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import equilibrium_state
from tests.tiny_population import TINY_POPULATION, tiny_population, tiny_population_file


@pytest.mark.parametrize("name", ["standard", "accuracy"])
def test_the_shipped_presets_load(name):
    assert name in preset_names()
    config = load_population(population_preset_path(name))
    assert config.trials > 0 and config.controllers == ["offset-free-lqg", "paper-lqg"]


def test_the_standard_population_is_the_one_the_issue_asks_for():
    """200 patients, 3.5-6.5 kg, +-30 %, 25-35 psi, 2-10 mm, the paper's noise, motion on."""
    config = load_population(population_preset_path("standard"))
    population = config.population
    assert config.trials == 200
    assert (population.head_mass_kg.low, population.head_mass_kg.high) == (3.5, 6.5)
    for name in ("stiffness", "leak", "inlet_conductance", "outlet_conductance"):
        draw = getattr(population, f"{name}_factor")
        assert (draw.low, draw.high) == (0.7, 1.3)
    psi_pa = 6894.757
    assert population.supply_gauge_pressure_pa.low == pytest.approx(25 * psi_pa, abs=1)
    assert population.supply_gauge_pressure_pa.high == pytest.approx(35 * psi_pa, abs=1)
    assert (population.step_size_m.low, population.step_size_m.high) == (0.002, 0.010)
    paper_noise = load_scenario(asset_path("presets/paper_camera_noise.yaml")).cameras
    for name, camera in config.scenario.cameras.items():
        assert camera.error == paper_noise[name].error
    assert config.scenario.patient_motion.enabled


def test_an_unknown_preset_lists_the_shipped_ones():
    with pytest.raises(ConfigError, match="no population preset 'nope'; shipped: accuracy"):
        population_preset_path("nope")


def test_a_missing_file_is_named(tmp_path):
    with pytest.raises(MissingFileError, match="population file not found"):
        load_population(tmp_path / "none.yaml")


@pytest.mark.parametrize(
    "old, new, message",
    [
        ("head_mass_kg: {", "head_mass_kgs: {", "unknown field 'population.head_mass_kgs'"),
        ("{low: 3.5, high: 6.5}", "{low: 6.5, high: 3.5}", r"population.head_mass_kg.low = 6.5"),
        ("{low: 0.7, high: 1.3}", "{low: 0.0, high: 1.3}", r"stiffness_factor.low = 0.0"),
        ("paper-lqg]", "papr-lqg]", "controllers: "),
        ("[offset-free-lqg, paper-lqg]", "[paper-lqg, paper-lqg]", "no controller twice"),
        (
            "step_time_s: 4.0",
            "step_time_s: 9.0",
            r"tiny.yaml: step_time_s = 9.0: expected a step judged",
        ),
        ("step_time_s: 4.0", "step_time_s: 0.5", "after positioning_time_s"),
        (
            "[paper_camera_noise]",
            "[paper_noise]",
            "scenario_presets: no scenario preset 'paper_noise'; shipped: paper",
        ),
        ("duration_s: 14.0", "duration_s: -1.0", "duration_s"),
        ("inlet_authority_fraction: 0.9", "inlet_authority_fraction: 1.5", "authority_fraction"),
    ],
)
def test_a_bad_population_file_is_refused_naming_the_file_and_field(tmp_path, old, new, message):
    assert old in TINY_POPULATION
    path = tiny_population_file(tmp_path, TINY_POPULATION.replace(old, new, 1))
    with pytest.raises(ConfigError, match=message) as raised:
        load_population(path)
    assert str(path) in str(raised.value)


def test_a_population_needs_the_pneumatic_plant(tmp_path):
    text = TINY_POPULATION.replace("scenario:\n", "scenario:\n  plant: !PaperPlant {}\n")
    with pytest.raises(ConfigError, match="expected !PneumaticPlant"):
        load_population(tiny_population_file(tmp_path, text))


def test_a_trial_draws_the_same_patient_whatever_else_is_drawn(tmp_path):
    config = tiny_population(tmp_path)
    window = nominal_lift_window_m(config)
    later_first = [draw_patient(config, trial, window) for trial in (5, 2, 0)]
    in_order = [draw_patient(config, trial, window) for trial in range(6)]
    assert later_first == [in_order[5], in_order[2], in_order[0]]
    assert len({patient.seed for patient in in_order}) == 6
    other_seed = dataclasses.replace(config, seed=4)
    assert draw_patient(other_seed, 0, window) != in_order[0]


def test_draws_follow_their_stated_distributions(tmp_path):
    """Kolmogorov-Smirnov against each uniform range; both levels inside the lift window."""
    config = tiny_population(tmp_path)
    window = nominal_lift_window_m(config)
    patients = [draw_patient(config, trial, window) for trial in range(1000)]
    p = config.scenario.pneumatic
    population = config.population
    drawn = {
        "head_mass_kg": ([x.head_mass_kg for x in patients], population.head_mass_kg, 1.0),
        "stiffness": (
            [x.stiffness_n_m for x in patients],
            population.stiffness_factor,
            p.stiffness_n_m,
        ),
        "leak": (
            [x.leak_sonic_conductance_m3_s_pa for x in patients],
            population.leak_factor,
            p.leak_sonic_conductance_m3_s_pa,
        ),
        "supply": (
            [x.supply_gauge_pressure_pa for x in patients],
            population.supply_gauge_pressure_pa,
            1.0,
        ),
        "step": ([abs(x.step_m) for x in patients], population.step_size_m, 1.0),
    }
    for name, (values, draw, scale) in drawn.items():
        low, span = draw.low * scale, (draw.high - draw.low) * scale
        assert stats.kstest(values, stats.uniform(low, span).cdf).pvalue > 0.01, name
    ups = sum(x.step_m > 0 for x in patients)
    assert stats.binomtest(ups, len(patients)).pvalue > 0.01
    for x in patients:
        for lift in (x.positioned_lift_m, x.positioned_lift_m + x.step_m):
            assert window[0] <= lift <= window[1]


def test_a_step_larger_than_the_working_range_is_refused(tmp_path):
    config = tiny_population(tmp_path)
    config.population.step_size_m.low = config.population.step_size_m.high = 0.05
    with pytest.raises(ConfigError, match="population.step_size_m: a 50.00 mm step does not fit"):
        draw_patient(config, 0, nominal_lift_window_m(config))


def test_the_patients_plant_and_its_reach(tmp_path):
    """Reach: the rest lift with one valve fully open, from the plant's own equilibrium."""
    config = tiny_population(tmp_path)
    nominal = config.scenario.pneumatic
    patient = draw_patient(config, 1, nominal_lift_window_m(config))
    plant = patient_plant(nominal, patient)
    assert plant.head_mass_kg == patient.head_mass_kg
    assert plant.inlet.sonic_conductance_m3_s_pa == patient.inlet_sonic_conductance_m3_s_pa
    assert plant.outlet.sonic_conductance_m3_s_pa == patient.outlet_sonic_conductance_m3_s_pa
    assert plant.inlet.starting_current_a == nominal.inlet.starting_current_a
    lowest, highest = patient_reach(nominal, patient)
    full_inlet = equilibrium_state(plant, plant.inlet.saturation_current_a, 0.0)[LIFT]
    full_outlet = equilibrium_state(plant, 0.0, plant.outlet.saturation_current_a)[LIFT]
    assert (lowest, highest) == (full_outlet, full_inlet)


def test_a_heavier_head_reaches_less_high():
    config = load_population(population_preset_path("accuracy"))
    nominal = config.scenario.pneumatic
    base = Patient(
        0,
        0,
        4.0,
        nominal.stiffness_n_m,
        nominal.leak_sonic_conductance_m3_s_pa,
        nominal.inlet.sonic_conductance_m3_s_pa,
        nominal.outlet.sonic_conductance_m3_s_pa,
        nominal.supply_gauge_pressure_pa,
        0.005,
        0.002,
    )
    heavy = dataclasses.replace(base, head_mass_kg=6.0)
    sink_m = 2.0 * nominal.gravity_m_s2 / nominal.stiffness_n_m
    assert patient_reach(nominal, heavy)[1] == pytest.approx(
        patient_reach(nominal, base)[1] - sink_m, abs=2e-4
    )


def test_the_sweep_sets_the_reference_and_seed_of_the_scenario(tmp_path):
    config = tiny_population(tmp_path)
    scenario = sweep_scenario(config, (0.001, -0.002), seed=7)
    assert scenario.reference.step_times_s == [1.0, 4.0]
    assert scenario.reference.step_offsets_m == [0.001, -0.002]
    assert scenario.random_seed == 7
    assert config.scenario.reference.step_times_s != [1.0, 4.0]  # the population's is untouched
