"""pneumatic_design against the physics (air capacity, steady lift), scipy's ZOH and hand sums."""

import numpy as np
import pytest
import scipy.signal

from maskless.systems.control.valve_allocation import SplitRangeAllocation
from maskless.systems.plant.pneumatic_design import (
    allocation_point,
    linearize_pneumatic_plant,
    pneumatic_allocation,
    pneumatic_design_model,
    zero_order_hold,
)
from maskless.systems.plant.pneumatic_physics import (
    GAUGE_PRESSURE,
    LIFT,
    net_mass_flow_kg_s,
    valve_opening,
)
from maskless.systems.plant.pneumatic_plant import equilibrium_state, load_pneumatic_parameters


@pytest.fixture(scope="module")
def p():
    return load_pneumatic_parameters()


@pytest.mark.parametrize("inlet_a", [0.08, 0.12, 0.16])
def test_linearized_slow_pole_matches_flow_time_constant(p, inlet_a):
    A, _, _ = linearize_pneumatic_plant(p, inlet_a)
    slow = min(np.linalg.eigvals(A), key=lambda s: abs(s.real))
    state = equilibrium_state(p, inlet_a, 0.0)
    gauge, lift = state[GAUGE_PRESSURE], state[LIFT]
    opening = valve_opening(inlet_a, p.inlet)
    dp = 1.0
    dq_dp = (
        net_mass_flow_kg_s(gauge + dp, opening, 0.0, p)
        - net_mass_flow_kg_s(gauge - dp, opening, 0.0, p)
    ) / (2 * dp)
    RT = p.gas_constant_j_kg_k * p.air_temperature_k
    volume = p.rest_volume_m3 + p.volume_per_lift_m2 * lift
    p_abs = p.atmospheric_pressure_pa + gauge
    # Air capacity of the bladder, with the head following the pressure quasi-statically.
    capacity = volume / (p.polytropic_exponent * RT) + (
        p_abs * p.volume_per_lift_m2 * p.contact_area_m2 / (p.stiffness_n_m * RT)
    )
    tau = capacity / -dq_dp
    assert abs(slow.imag) < 1e-9
    assert -1.0 / slow.real == pytest.approx(tau, rel=0.10)


def scipy_zoh(A, B, period_s):
    C, D = np.zeros((1, A.shape[0])), np.zeros((1, B.shape[1]))
    Ad, Bd, *_ = scipy.signal.cont2discrete((A, B, C, D), period_s, method="zoh")
    return Ad, Bd


def test_zero_order_hold_matches_scipy_on_a_two_input_system():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((3, 3)) - 2.0 * np.eye(3)
    B = rng.standard_normal((3, 2))
    for period_s in (0.01, 0.048, 0.5):
        Ad, Bd = zero_order_hold(A, B, period_s)
        expected_Ad, expected_Bd = scipy_zoh(A, B, period_s)
        np.testing.assert_allclose(Ad, expected_Ad, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(Bd, expected_Bd, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("valve, inlet_a, outlet_a", [("inlet", 0.12, 0.0), ("outlet", 0.165, 0.1)])
def test_zero_order_hold_matches_scipy_on_the_linearised_plant(p, valve, inlet_a, outlet_a):
    A, B, _ = linearize_pneumatic_plant(p, inlet_a, outlet_a, valve)
    Ad, Bd = zero_order_hold(A, B, 0.048)
    expected_Ad, expected_Bd = scipy_zoh(A, B, 0.048)
    np.testing.assert_allclose(Ad, expected_Ad, rtol=1e-9, atol=1e-12 * np.abs(expected_Ad).max())
    np.testing.assert_allclose(Bd, expected_Bd, rtol=1e-9, atol=1e-12 * np.abs(expected_Bd).max())


# The split range of tests/test_valve_allocation.py: the outlet below 0, the inlet above.
KNOTS = np.array([-0.01, 0.0, 0.004, 0.011, 0.018])
INLET = np.array([0.0, 0.0, 0.07, 0.12, 0.165])
OUTLET = np.array([0.165, 0.06, 0.0, 0.0, 0.0])


@pytest.mark.parametrize(
    "command, valve, inlet_a, outlet_a, slope",
    [
        # Inside the third segment: the inlet at 0.07 + 2/7 of 0.05 A, 0.05 A over 7 mm.
        (0.006, "inlet", 0.07 + 0.05 * 2 / 7, 0.0, 0.05 / 0.007),
        # At a knot, the segment below: 0.07 A over the 4 mm from 0.
        (0.004, "inlet", 0.07, 0.0, 0.07 / 0.004),
        # Below 0 the outlet opens as the command falls: -0.105 A over 10 mm.
        (-0.005, "outlet", 0.0, 0.1125, -0.105 / 0.01),
        # Past either end, the end segment.
        (-0.02, "outlet", 0.0, 0.165, -0.105 / 0.01),
        (0.03, "inlet", 0.165, 0.0, 0.045 / 0.007),
    ],
)
def test_allocation_point_by_hand(command, valve, inlet_a, outlet_a, slope):
    point = allocation_point(SplitRangeAllocation(KNOTS, INLET, OUTLET), command)
    assert point.valve == valve
    assert point.inlet_current_a == pytest.approx(inlet_a, abs=1e-15)
    assert point.outlet_current_a == pytest.approx(outlet_a, abs=1e-15)
    assert point.amps_per_command == pytest.approx(slope, rel=1e-12)


@pytest.mark.parametrize("lift_m", [0.006, 0.009, 0.013])
def test_design_model_dc_gain_is_the_slope_of_the_allocated_steady_lift(p, lift_m):
    # Central differences of the physics' steady lift through the allocation: no linearisation.
    allocation = pneumatic_allocation(p, 0.003)
    model = pneumatic_design_model(p, allocation, lift_m, 0.048)
    h = 1e-7  # m of command, inside one segment of the allocation

    def steady_lift(command):
        return equilibrium_state(p, *allocation.currents(command))[LIFT]

    slope = (steady_lift(lift_m + h) - steady_lift(lift_m - h)) / (2 * h)
    assert model.dc_gain() == pytest.approx(slope, rel=1e-4)
    assert model.sample_period_s == 0.048 and model.operating_input == lift_m
