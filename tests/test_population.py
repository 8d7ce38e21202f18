"""Populations: files and presets refused or loaded, draws per trial and their distributions."""

import dataclasses

import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource
from scipy import stats

from maskless.diagrams.population import (
    Patient,
    draw_patient,
    lift_window_m,
    load_population,
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
from maskless.systems.plant.pneumatic_plant import add_pneumatic_plant, equilibrium_state
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
            "scenario_presets: no scenario preset 'paper_noise'; shipped: noisy_pressure_sensor, "
            "paper",
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
    later_first = [draw_patient(config, trial) for trial in (5, 2, 0)]
    in_order = [draw_patient(config, trial) for trial in range(6)]
    assert later_first == [in_order[5], in_order[2], in_order[0]]
    assert len({patient.seed for patient in in_order}) == 6
    other_seed = dataclasses.replace(config, seed=4)
    assert draw_patient(other_seed, 0) != in_order[0]


def test_draws_follow_their_stated_distributions(tmp_path):
    """Kolmogorov-Smirnov against each uniform range; both levels in the patient's own range."""
    config = tiny_population(tmp_path)
    patients = [draw_patient(config, trial) for trial in range(1000)]
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
    fits = 0
    for x in patients:
        low, high = lift_window_m(patient_plant(p, x), population)
        levels = (x.positioned_lift_m, x.positioned_lift_m + x.step_m)
        if abs(x.step_m) <= high - low:
            fits += 1
            assert all(low <= lift <= high for lift in levels)
        else:  # from the range's far end, past the other
            assert x.positioned_lift_m == (low if x.step_m > 0 else high)
    assert len(patients) / 2 < fits < len(patients)  # both branches taken


def test_a_step_larger_than_the_nominal_working_range_is_refused_at_load(tmp_path):
    text = TINY_POPULATION.replace("{low: 0.002, high: 0.010}", "{low: 0.002, high: 0.05}")
    with pytest.raises(ConfigError, match=r"population.step_size_m.high = 0.05: expected a step"):
        load_population(tiny_population_file(tmp_path, text))


def test_the_working_range_is_where_the_valves_hold_the_head(tmp_path):
    """Bottom: both shut, plus the margin; top: the inlet at its authority fraction."""
    config = tiny_population(tmp_path)
    p, population = config.scenario.pneumatic, config.population
    low, high = lift_window_m(p, population)
    shut = equilibrium_state(p, 0.0, 0.0)[LIFT]
    top = p.inlet.starting_current_a + population.inlet_authority_fraction * p.inlet.current_span_a
    assert low == pytest.approx(shut + population.lift_margin_m, abs=1e-12)
    assert high == equilibrium_state(p, top, 0.0)[LIFT]
    sink_m = (p.head_mass_kg - p.nominal_head_mass_kg) * p.gravity_m_s2 / p.stiffness_n_m
    assert shut == pytest.approx(-sink_m, abs=1e-9)  # an empty bladder carries the head alone


def test_the_patients_plant_and_its_reach(tmp_path):
    """Reach: where the plant, run open loop, settles with one valve fully open (or none)."""
    config = tiny_population(tmp_path)
    nominal = config.scenario.pneumatic
    patient = draw_patient(config, 1)
    plant = patient_plant(nominal, patient)
    assert plant.head_mass_kg == patient.head_mass_kg
    assert plant.inlet.sonic_conductance_m3_s_pa == patient.inlet_sonic_conductance_m3_s_pa
    assert plant.outlet.sonic_conductance_m3_s_pa == patient.outlet_sonic_conductance_m3_s_pa
    assert plant.inlet.starting_current_a == nominal.inlet.starting_current_a
    # Past saturation by the spool's play, so a spool lagging in its band still opens fully.
    outlet_a = plant.outlet.saturation_current_a + 2 * plant.outlet.play_half_width_a
    inlet_a = plant.inlet.saturation_current_a + 2 * plant.inlet.play_half_width_a
    reach = {
        "both valves": (patient_reach(nominal, patient), (outlet_a, 0.0)),
        "inlet only": (patient_reach(nominal, patient, outlet_used=False), (0.0, 0.0)),
    }
    for name, (lifts, (lowest_outlet_a, _)) in reach.items():
        for lift, currents in zip(lifts, [(0.0, lowest_outlet_a), (inlet_a, 0.0)], strict=True):
            assert settled_lift_m(plant, *currents) == pytest.approx(lift, abs=2e-5), name
    assert reach["both valves"][0][0] < reach["inlet only"][0][0]


def settled_lift_m(p, inlet_a, outlet_a):
    """The compiled plant run open loop from the rest with both valves shut, for 300 s."""
    builder = DiagramBuilder()
    plant = add_pneumatic_plant(builder, p, equilibrium_state(p, 0.0, 0.0), p.simulation_step_s)
    for port, value in (("inlet_valve_current_a", inlet_a), ("outlet_valve_current_a", outlet_a)):
        source = builder.AddSystem(ConstantVectorSource([value]))
        builder.Connect(source.get_output_port(), plant.inputs[port])
    builder.ExportOutput(plant.outputs["head_height_m"], "head_height_m")
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(300.0)
    height = diagram.GetOutputPort("head_height_m").Eval(simulator.get_context())[0]
    return height - p.rest_head_height_m


def test_a_heavier_head_reaches_less_high():
    config = load_population(population_preset_path("accuracy"))
    nominal = config.scenario.pneumatic
    base = Patient(
        0,
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


def test_more_seeds_run_the_same_patient_with_new_noise_and_keep_the_first(tmp_path):
    config = tiny_population(tmp_path)
    runs = [draw_patient(config, 3, run) for run in range(3)]
    assert [run.run for run in runs] == [0, 1, 2]
    assert len({run.seed for run in runs}) == 3
    same = [dataclasses.replace(run, run=0, seed=0) for run in runs]
    assert same[0] == same[1] == same[2]  # the plant and the reference
    assert draw_patient(config, 3) == runs[0]
