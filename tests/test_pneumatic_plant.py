"""The pneumatic plant's forms against the physics, and a written head against a rebuilt one."""

import dataclasses

import numpy as np
import pytest
from pydrake.symbolic import if_then_else
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink
from system_harness import port_layout

from maskless.errors import ConfigError
from maskless.systems.plant.pneumatic_physics import (
    GAUGE_PRESSURE,
    LIFT,
    head_force_n,
    valve_opening,
)
from maskless.systems.plant.pneumatic_plant import (
    COMPILED_PARAMETER_NAMES,
    PARAMETER_NAMES,
    STEP_PARAMETERS,
    SWEPT_PARAMETERS,
    PneumaticPlant,
    add_pneumatic_plant,
    beyond_travel,
    compiled_parameter_vector,
    equilibrium_state,
    load_pneumatic_parameters,
    make_pneumatic_plant,
    parameters_from_vector,
    pneumatic_parameters,
    set_pneumatic_parameters,
    steady_gauge_pressure_pa,
    validate_pneumatic_parameters,
)


@pytest.fixture(scope="module")
def p():
    return load_pneumatic_parameters()


def time_derivatives(plant, state, inlet_a, outlet_a, parameters=None):
    context = plant.CreateDefaultContext()
    if parameters is not None:
        plant.set_parameters(context, parameters)
    context.SetContinuousState(state)
    plant.GetInputPort("inlet_valve_current_a").FixValue(context, [inlet_a])
    plant.GetInputPort("outlet_valve_current_a").FixValue(context, [outlet_a])
    return plant.EvalTimeDerivatives(context).CopyToVector()


def test_ports(p):
    plant = PneumaticPlant(p)
    assert port_layout(plant) == (
        {"inlet_valve_current_a": 1, "outlet_valve_current_a": 1},
        {"head_height_m": 1, "state": 5, "bladder_gauge_pressure_pa": 1},
    )
    discrete = make_pneumatic_plant(p, equilibrium_state(p, 0.0, 0.0), p.simulation_step_s)
    assert port_layout(discrete) == port_layout(plant)


def test_the_gauge_pressure_port_reads_the_state(p):
    state = np.array([1500.0, 0.004, 0.01, 0.1, 0.07])
    plant = PneumaticPlant(p, state)
    context = plant.CreateDefaultContext()
    assert plant.GetOutputPort("bladder_gauge_pressure_pa").Eval(context)[0] == 1500.0
    discrete = make_pneumatic_plant(p, state, p.simulation_step_s)
    context = discrete.CreateDefaultContext()
    assert discrete.GetOutputPort("bladder_gauge_pressure_pa").Eval(context)[0] == 1500.0


def test_scalar_conversion_agrees_with_float(p):
    plant = PneumaticPlant(p)
    state = np.array([1500.0, 0.004, 0.01, 0.1, 0.07])
    expected = time_derivatives(plant, state, 0.12, 0.065)
    for converted, value_of in (
        (plant.ToAutoDiffXd(), lambda x: x.value()),
        (plant.ToSymbolic(), lambda x: x.Evaluate()),
    ):
        context = converted.CreateDefaultContext()
        context.SetContinuousState(state)
        converted.GetInputPort("inlet_valve_current_a").FixValue(context, [0.12])
        converted.GetInputPort("outlet_valve_current_a").FixValue(context, [0.065])
        derivatives = converted.EvalTimeDerivatives(context).CopyToVector()
        np.testing.assert_allclose([value_of(x) for x in derivatives], expected, rtol=1e-12)


@pytest.mark.parametrize("inlet_a", [0.0, 0.07, 0.1, 0.14, 0.165])
def test_equilibrium_state_is_at_rest(p, inlet_a):
    state = equilibrium_state(p, inlet_a, 0.0)
    rates = time_derivatives(PneumaticPlant(p), state, inlet_a, 0.0)
    # Pressure to 1e-4 Pa/s, lift, its rate and the spools to numerical zero.
    assert abs(rates[0]) < 1e-4
    np.testing.assert_allclose(rates[1:], 0.0, atol=1e-9)


def test_steady_lift_range_of_issue_5(p):
    lift_low = equilibrium_state(p, 0.060, 0.0)[LIFT]
    lift_high = equilibrium_state(p, 0.165, 0.0)[LIFT]
    assert lift_low == pytest.approx(0.0, abs=1e-9)
    assert 0.010 <= lift_high <= 0.020
    lifts = [equilibrium_state(p, i, 0.0)[LIFT] for i in np.linspace(0.062, 0.165, 12)]
    assert np.all(np.diff(lifts) > 0)


def run(system, inlet_a, outlet_a, duration_s, period_s, accuracy=None):
    builder = DiagramBuilder()
    builder.AddSystem(system)
    for name, value in (("inlet_valve_current_a", inlet_a), ("outlet_valve_current_a", outlet_a)):
        source = builder.AddSystem(ConstantVectorSource([value]))
        builder.Connect(source.get_output_port(), system.GetInputPort(name))
    sink = builder.AddSystem(VectorLogSink(1, period_s))
    builder.Connect(system.GetOutputPort("head_height_m"), sink.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    if accuracy is not None:
        simulator.get_mutable_integrator().set_target_accuracy(accuracy)
    simulator.AdvanceTo(duration_s)
    log = sink.FindLog(simulator.get_context())
    return log.sample_times(), log.data()[0]


_CONTINUOUS = {}
SLEWS = [((0.0, 0.0), (0.165, 0.0)), ((0.165, 0.0), (0.0, 0.165))]


def slew_error_m(p, head_mass_kg, start, step, step_divisor):
    """Max |compiled - continuous| head height over a 20 s full-valve slew.

    Logged every step of the compiled plant; the continuous run (Drake RK3, target accuracy 1e-8)
    is cached.
    """
    q = dataclasses.replace(p, head_mass_kg=head_mass_kg)
    state = equilibrium_state(q, *start)
    h = q.simulation_step_s / step_divisor
    key = (head_mass_kg, start, step)
    if key not in _CONTINUOUS:
        log_period = q.simulation_step_s / 4
        _CONTINUOUS[key] = run(PneumaticPlant(q, state), *step, 20.0, log_period, 1e-8)
    t_c, y_c = _CONTINUOUS[key]
    t_d, y_d = run(make_pneumatic_plant(q, state, h), *step, 20.0, h)
    assert abs(y_c[-1] - y_c[0]) > 5e-3  # it did move
    return np.max(np.abs(np.interp(t_d, t_c, y_c) - y_d))


@pytest.mark.parametrize("head_mass_kg", [4.0, 6.0])
@pytest.mark.parametrize("start, step", SLEWS, ids=["inlet", "outlet"])
def test_compiled_plant_follows_the_continuous_one(p, head_mass_kg, start, step):
    # The bound assets/pneumatic.yaml states for the shipped step (full-valve slews).
    assert slew_error_m(p, head_mass_kg, start, step, 1) < 1.1e-3


@pytest.mark.parametrize("head_mass_kg", [4.0, 6.0])
@pytest.mark.parametrize("start, step", SLEWS, ids=["inlet", "outlet"])
def test_compiled_plant_converges_at_first_order(p, head_mass_kg, start, step):
    coarse = slew_error_m(p, head_mass_kg, start, step, 1)
    fine = slew_error_m(p, head_mass_kg, start, step, 4)
    assert fine < 0.5e-3
    assert 3.0 < coarse / fine < 5.0  # a quarter of the step, a quarter of the error


@pytest.mark.parametrize("currents", [(0.0, 0.0), (0.11, 0.0)])
def test_compiled_plant_exact_at_rest(p, currents):
    state = equilibrium_state(p, *currents)
    t_d, y_d = run(make_pneumatic_plant(p, state, p.simulation_step_s), *currents, 5.0, 0.5)
    np.testing.assert_allclose(y_d, p.rest_head_height_m + state[LIFT], atol=1e-9)
    t_c, y_c = run(PneumaticPlant(p, state), *currents, 5.0, 0.5, 1e-8)
    np.testing.assert_allclose(y_c, y_d, atol=1e-9)


def test_head_mass_in_context_moves_the_equilibrium(p):
    plant = PneumaticPlant(p)
    rest = equilibrium_state(p, 0.0, 0.0)
    heavier = dataclasses.replace(p, head_mass_kg=p.head_mass_kg + 1.25)
    shifted = rest.copy()
    shifted[LIFT] -= 1.25 * p.gravity_m_s2 / p.stiffness_n_m  # zero gauge: delta_m g / k
    np.testing.assert_allclose(time_derivatives(plant, shifted, 0.0, 0.0, heavier), 0.0, atol=1e-9)
    # The old rest is not an equilibrium for the heavier head: it accelerates at -delta_m g / m.
    rates = time_derivatives(plant, rest, 0.0, 0.0, heavier)
    assert rates[2] == pytest.approx(-1.25 * p.gravity_m_s2 / heavier.head_mass_kg, rel=1e-9)


@pytest.mark.parametrize("field, value", [("stiffness_n_m", -4000.0), ("polytropic_exponent", 1.6)])
def test_validation_names_the_field(p, field, value):
    validate_pneumatic_parameters(p)
    with pytest.raises(ConfigError, match=f"pneumatic.{field}"):
        validate_pneumatic_parameters(dataclasses.replace(p, **{field: value}))


def test_new_parameters_in_a_used_context_take_effect(p):
    # The plant keeps its constants in a cache entry on the numeric parameter: writing new ones
    # after an evaluation must change the next one, as a plant built with them computes it.
    heavy = dataclasses.replace(p, head_mass_kg=6.0)
    state = equilibrium_state(p, 0.12, 0.0)
    plant = PneumaticPlant(p)
    context = plant.CreateDefaultContext()
    context.SetContinuousState(state)
    plant.GetInputPort("inlet_valve_current_a").FixValue(context, [0.12])
    plant.GetInputPort("outlet_valve_current_a").FixValue(context, [0.0])
    before = plant.EvalTimeDerivatives(context).CopyToVector()
    plant.set_parameters(context, heavy)
    after = plant.EvalTimeDerivatives(context).CopyToVector()
    np.testing.assert_array_equal(after, time_derivatives(PneumaticPlant(heavy), state, 0.12, 0.0))
    assert not np.array_equal(before, after)


def slew_with_parameters(built_with, built_start, context_parameters, written=None):
    """Head heights (every step) of a compiled plant built with one head and run with another.

    Built with ``built_with`` at ``built_start`` and run with ``written`` written into its
    Context: rest at 0.11 A on the inlet, then a slew on the inlet to 0.165 A and on the outlet
    to 0.1 A.
    """
    builder = DiagramBuilder()
    plant = add_pneumatic_plant(
        builder,
        built_with,
        built_start,
        built_with.simulation_step_s,
        name="plant",
        context_parameters=context_parameters,
    )
    for port, current in (("inlet_valve_current_a", 0.165), ("outlet_valve_current_a", 0.1)):
        source = builder.AddSystem(ConstantVectorSource([current]))
        builder.Connect(source.get_output_port(), plant.inputs[port])
    sink = builder.AddSystem(VectorLogSink(1, built_with.simulation_step_s))
    builder.Connect(plant.outputs["head_height_m"], sink.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    if written is not None:
        set_pneumatic_parameters(diagram, simulator.get_mutable_context(), written, name="plant")
    simulator.AdvanceTo(3.0)
    return sink.FindLog(simulator.get_context()).data()[0]


@pytest.mark.parametrize(
    "context_parameters, changes",
    [
        (SWEPT_PARAMETERS, {"head_mass_kg": 6.0}),
        (SWEPT_PARAMETERS, {"stiffness_n_m": 5000.0, "leak_sonic_conductance_m3_s_pa": 9e-9}),
        (
            STEP_PARAMETERS,
            {"head_mass_kg": 4.0, "rest_volume_m3": 0.003, "polytropic_exponent": 1.0},
        ),
    ],
    ids=["head", "bladder", "every-constant"],
)
def test_parameters_written_in_a_context_run_as_a_plant_built_with_them(
    p, context_parameters, changes
):
    changed = dataclasses.replace(p, **changes)
    start = equilibrium_state(p, 0.11, 0.0)
    written = slew_with_parameters(p, start, context_parameters, changed)
    # The reference: a plant built with the changed constants as numbers, at their own rest at
    # the same currents (where set_pneumatic_parameters puts the plant by default).
    rebuilt = slew_with_parameters(changed, equilibrium_state(changed, 0.11, 0.0), ())
    assert abs(rebuilt[0] - slew_with_parameters(p, start, ())[0]) > 1e-4  # the head moved
    np.testing.assert_allclose(written, rebuilt, rtol=0, atol=1e-14)


def test_a_fresh_context_runs_the_built_plant(p):
    start = equilibrium_state(p, 0.11, 0.0)
    np.testing.assert_array_equal(
        slew_with_parameters(p, start, SWEPT_PARAMETERS, written=None),
        slew_with_parameters(p, start, SWEPT_PARAMETERS, written=p),
    )


def test_parameter_names_and_sizes(p):
    start = equilibrium_state(p, 0.11, 0.0)
    plant = make_pneumatic_plant(p, start, p.simulation_step_s)
    source = plant.GetSubsystemByName("pneumatic_plant.parameters")
    assert len(PARAMETER_NAMES) == 36 and PARAMETER_NAMES[9] == "inlet.sonic_conductance_m3_s_pa"
    assert (
        source.names
        == COMPILED_PARAMETER_NAMES
        == (
            *PARAMETER_NAMES,
            "state_origin.gauge_pressure_pa",
            "state_origin.lift_m",
            "state_origin.lift_rate_m_s",
            "state_origin.inlet_spool_current_a",
            "state_origin.outlet_spool_current_a",
        )
    )
    assert set(COMPILED_PARAMETER_NAMES) - set(source.fixed_names) == set(SWEPT_PARAMETERS)
    context = plant.CreateDefaultContext()
    held = source.get_values(plant.GetSubsystemContext(source, context))
    np.testing.assert_array_equal(held, compiled_parameter_vector(p, start))
    assert pneumatic_parameters(plant, context) == p


def test_a_bad_parameter_vector_names_what_was_expected(p):
    plant = make_pneumatic_plant(p, equilibrium_state(p, 0.0, 0.0), p.simulation_step_s)
    source = plant.GetSubsystemByName("pneumatic_plant.parameters")
    context = plant.CreateDefaultContext()
    source_context = plant.GetMutableSubsystemContext(source, context)
    with pytest.raises(ValueError, match="3 values; expected 41: supply_gauge_pressure_pa, .*"):
        source.set_values(source_context, np.ones(3))
    with pytest.raises(ValueError, match="has 35 entries; expected 36: .*simulation_step_s$"):
        parameters_from_vector(np.ones(35))
    with pytest.raises(ValueError, match="initial_state has 4 entries; expected 5: gauge_pres"):
        set_pneumatic_parameters(plant, context, p, initial_state=np.zeros(4))
    # A constant the plant was built with as a number cannot change in its Context.
    with pytest.raises(ValueError, match=r"rest_volume_m3 = 0.003 \(built with 0.0037\)"):
        set_pneumatic_parameters(plant, context, dataclasses.replace(p, rest_volume_m3=0.003))
    with pytest.raises(ConfigError, match="pneumatic.head_mass_kg"):
        set_pneumatic_parameters(plant, context, dataclasses.replace(p, head_mass_kg=-1.0))
    with pytest.raises(ValueError, match="context_parameters \\['simulation_step_s'\\]"):
        make_pneumatic_plant(
            p, equilibrium_state(p, 0.0, 0.0), 0.1, context_parameters=("simulation_step_s",)
        )


def _with_leak(p, conductance):
    return dataclasses.replace(p, leak_sonic_conductance_m3_s_pa=conductance)


def test_a_sealed_bladder_with_the_inlet_open_fills_to_the_supply_and_pins_the_head(p):
    sealed = _with_leak(p, 0.0)
    inlet_open = valve_opening(p.inlet.saturation_current_a, p.inlet)
    # No leak and the outlet shut: nothing balances the inlet short of the supply's pressure.
    assert steady_gauge_pressure_pa(sealed, inlet_open, 0.0) == sealed.supply_gauge_pressure_pa
    state = equilibrium_state(sealed, p.inlet.saturation_current_a, 0.0)
    # Past the travel, on the model's stop, and at rest there: no net force on the head.
    assert state[LIFT] > p.max_lift_m and beyond_travel(sealed, state)
    force = head_force_n(state[GAUGE_PRESSURE], state[LIFT], 0.0, sealed)
    assert abs(force) < 1e-9 * sealed.supply_gauge_pressure_pa * sealed.contact_area_m2


def test_a_sealed_bladder_with_both_valves_shut_holds_the_atmosphere(p):
    assert steady_gauge_pressure_pa(_with_leak(p, 0.0), 0.0, 0.0) == 0.0


def test_a_bladder_open_to_the_vacuum_drains_to_it_and_pins_the_head_low(p):
    outlet_open = valve_opening(p.outlet.saturation_current_a, p.outlet)
    sealed = _with_leak(p, 0.0)
    vacuum_gauge = p.vacuum_absolute_pressure_pa - p.atmospheric_pressure_pa
    assert steady_gauge_pressure_pa(sealed, 0.0, outlet_open) == vacuum_gauge
    state = equilibrium_state(sealed, 0.0, p.outlet.saturation_current_a)
    assert beyond_travel(sealed, state)


def test_the_nominal_working_range_is_inside_the_travel(p):
    for current in np.linspace(p.inlet.starting_current_a, p.inlet.saturation_current_a, 5):
        assert not beyond_travel(p, equilibrium_state(p, current, 0.0))


def test_time_factors_name_only_constants_that_may_change(p):
    state = equilibrium_state(p, 0.0, 0.0)
    for name in ("no_such_constant", "simulation_step_s"):
        with pytest.raises(ConfigError, match=rf"time_factors \['{name}'\]: expected some of"):
            make_pneumatic_plant(
                p, state, p.simulation_step_s, time_factors=lambda t, n=name: {n: t * 0 + 1}
            )


@pytest.mark.parametrize("context_parameters", [(), SWEPT_PARAMETERS])
def test_a_time_factor_scales_its_constant_from_its_time_on(p, context_parameters):
    """A halved supply from 1 s on runs as a plant built with half the supply, after 1 s only.

    With the supply in the Context, the factor scales what is written there.
    """
    written = dataclasses.replace(p, supply_gauge_pressure_pa=1.5 * p.supply_gauge_pressure_pa)
    halved = dataclasses.replace(
        written, supply_gauge_pressure_pa=0.75 * p.supply_gauge_pressure_pa
    )
    state = equilibrium_state(p, 0.14, 0.0)

    def factors(time):
        return {"supply_gauge_pressure_pa": if_then_else(time >= 1.0, 0.5, 1.0)}

    def next_state(plant_parameters, time_s, time_factors=None, write=None):
        diagram = make_pneumatic_plant(
            plant_parameters,
            state,
            p.simulation_step_s,
            context_parameters=context_parameters,
            time_factors=time_factors,
        )
        context = diagram.CreateDefaultContext()
        if write is not None:
            set_pneumatic_parameters(diagram, context, write, initial_state=state)
        context.SetTime(time_s)
        for port, current in (("inlet_valve_current_a", 0.14), ("outlet_valve_current_a", 0.0)):
            diagram.GetInputPort(port).FixValue(context, [current])
        plant = diagram.GetSubsystemByName("pneumatic_plant")
        plant_context = diagram.GetMutableSubsystemContext(plant, context)
        return plant.EvalUniquePeriodicDiscreteUpdate(plant_context).value()

    # Built with the written constants, or built nominal with them written into the Context.
    built, write = (p, written) if context_parameters else (written, None)
    before = next_state(built, 0.5, factors, write)
    after = next_state(built, 1.5, factors, write)
    np.testing.assert_allclose(before, next_state(written, 0.5), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(after, next_state(halved, 1.5), rtol=1e-12, atol=1e-12)
    assert abs(after[GAUGE_PRESSURE] - before[GAUGE_PRESSURE]) > 1e-3  # Pa: it did change
