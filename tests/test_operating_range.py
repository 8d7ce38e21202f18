"""The operating range: DC gains and time constants against finite differences of the plant."""

import numpy as np
import pytest

from maskless.analysis.operating_range import (
    default_operating_ranges,
    mode_time_constants_s,
    operating_range,
    valve_currents_a,
)
from maskless.systems.plant.pneumatic_design import linearize_pneumatic_plant
from maskless.systems.plant.pneumatic_physics import (
    GAUGE_PRESSURE,
    LIFT,
    LIFT_RATE,
    state_derivatives,
)
from maskless.systems.plant.pneumatic_plant import equilibrium_state, load_pneumatic_parameters


@pytest.fixture(scope="module")
def p():
    return load_pneumatic_parameters()


@pytest.fixture(scope="module")
def ranges(p):
    return default_operating_ranges(p, 8)


def steady_lift(p, inlet_a, outlet_a):
    return equilibrium_state(p, inlet_a, outlet_a)[LIFT]


# Currents clear of the kinks of the flow law (the leak's laminar segment ends near 75 mA inlet).
@pytest.mark.parametrize(
    "valve, current_a, held_a",
    [("inlet", 0.065, 0.0), ("inlet", 0.100, 0.0), ("inlet", 0.150, 0.0), ("outlet", 0.090, 0.165)],
)
def test_dc_gain_is_the_slope_of_the_steady_lift_curve(p, valve, current_a, held_a):
    sweep = operating_range(p, valve, [current_a], held_a)
    h = 1e-5  # A

    def lift(current):
        return steady_lift(p, *((current, held_a) if valve == "inlet" else (held_a, current)))

    slope = (lift(current_a + h) - lift(current_a - h)) / (2 * h)
    assert sweep.dc_gain_m_per_a[0] == pytest.approx(slope, rel=1e-4)


def finite_difference_jacobian(p, state, inlet_a, outlet_a, indices):
    """d(state')/d(state) on ``indices`` by central differences of the physics (no AutoDiff)."""
    steps = {GAUGE_PRESSURE: 1e-2, LIFT: 1e-8, LIFT_RATE: 1e-8}
    J = np.zeros((len(indices), len(indices)))
    for column, k in enumerate(indices):
        plus, minus = state.copy(), state.copy()
        plus[k] += steps[k]
        minus[k] -= steps[k]
        difference = np.array(state_derivatives(plus, inlet_a, outlet_a, p)) - np.array(
            state_derivatives(minus, inlet_a, outlet_a, p)
        )
        J[:, column] = difference[list(indices)] / (2 * steps[k])
    return J


@pytest.mark.parametrize(
    "valve, current_a, held_a", [("inlet", 0.120, 0.0), ("outlet", 0.130, 0.165)]
)
def test_time_constants_match_a_finite_difference_jacobian(p, valve, current_a, held_a):
    inlet_a, outlet_a = (current_a, held_a) if valve == "inlet" else (held_a, current_a)
    state = equilibrium_state(p, inlet_a, outlet_a)
    # The spool's lag drives the air and the head but is not driven by them (block triangular):
    # the modes are those of (pressure, lift, rate) with the spool fixed, and the spool's own.
    J = finite_difference_jacobian(p, state, inlet_a, outlet_a, (GAUGE_PRESSURE, LIFT, LIFT_RATE))
    spool_tau = (p.inlet if valve == "inlet" else p.outlet).time_constant_s
    expected = sorted(
        [*{round(-1.0 / ev.real, 12) for ev in np.linalg.eigvals(J)}, spool_tau], reverse=True
    )
    sweep = operating_range(p, valve, [current_a], held_a)
    # One entry per state; the complex pair is one mode, and its row is padded with NaN.
    row = sweep.time_constants_s[0]
    assert row.size == 4 and np.isnan(row[len(expected) :]).all()
    np.testing.assert_allclose(row[: len(expected)], expected, rtol=1e-4)
    assert sweep.slow_time_constant_s[0] == np.nanmax(row)


def test_mode_time_constants_closed_form():
    A = np.zeros((4, 4))
    A[0, 0], A[1, 1] = -2.0, -0.5
    A[2:, 2:] = [[-4.0, 3.0], [-3.0, -4.0]]  # a complex pair -4 ± 3j: one mode, tau 0.25 s
    np.testing.assert_allclose(mode_time_constants_s(A), [2.0, 0.5, 0.25])
    integrator = np.array([[0.0, 1.0], [0.0, -1.0]])
    assert mode_time_constants_s(integrator).tolist() == [np.inf, 1.0]


def test_steady_lift_balances_the_head_on_the_pressure(p, ranges):
    # Force balance at rest, inside the travel limits: gauge * area + stiffness * (unloaded lift -
    # lift) = weight, where the nominal head rests at zero lift on the unpressurised bladder.
    offset_m = (p.nominal_head_mass_kg - p.head_mass_kg) * p.gravity_m_s2 / p.stiffness_n_m
    for sweep in ranges.values():
        np.testing.assert_allclose(
            sweep.gauge_pressure_pa * p.contact_area_m2 / p.stiffness_n_m + offset_m,
            sweep.lift_m,
            atol=1e-9,
        )


def test_default_sweeps_span_the_valves_and_meet_at_full_inlet(p, ranges):
    inlet, outlet = ranges["inlet"], ranges["outlet"]
    for sweep, valve in ((inlet, p.inlet), (outlet, p.outlet)):
        assert sweep.currents_a[[0, -1]].tolist() == [
            valve.starting_current_a,
            valve.saturation_current_a,
        ]
    assert (inlet.held_current_a, outlet.held_current_a) == (0.0, p.inlet.saturation_current_a)
    # At its starting current the outlet passes nothing: the state is the full inlet's.
    assert outlet.lift_m[0] == pytest.approx(inlet.lift_m[-1], abs=1e-12)
    assert np.all(np.diff(inlet.lift_m) > 0) and np.all(inlet.dc_gain_m_per_a > 0)
    assert np.all(np.diff(outlet.lift_m) < 0) and np.all(outlet.dc_gain_m_per_a < 0)
    assert inlet.lift_span_m == pytest.approx(inlet.lift_m[-1] - inlet.lift_m[0])


def test_linearize_about_the_outlet_drives_the_outlet_spool(p):
    A, B, C = linearize_pneumatic_plant(p, 0.165, 0.1, valve="outlet")
    # Only the spool's own equation sees the coil current: B = e_spool / tau.
    expected = np.zeros((4, 1))
    expected[3, 0] = 1.0 / p.outlet.time_constant_s
    np.testing.assert_allclose(B, expected, rtol=1e-9)
    assert A[3, 3] == pytest.approx(-1.0 / p.outlet.time_constant_s)
    inlet_A, _, _ = linearize_pneumatic_plant(p, 0.165, 0.1)
    assert A[0, 3] < 0 < inlet_A[0, 3]  # the outlet drains the bladder, the inlet fills it


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda p: valve_currents_a(p, "inlet", 1), "num_points = 1"),
        (lambda p: valve_currents_a(p, "inlet", 2.5), "num_points"),
        (lambda p: valve_currents_a(p, "middle", 5), "valve = 'middle'"),
        (lambda p: operating_range(p, "inlet", [0.1, 0.09], 0.0), "currents_a"),
        (lambda p: operating_range(p, "inlet", [], 0.0), "currents_a"),
        (lambda p: linearize_pneumatic_plant(p, 0.1, 0.0, valve="both"), "valve = 'both'"),
    ],
)
def test_bad_arguments_are_refused(p, call, match):
    with pytest.raises(ValueError, match=match):
        call(p)
