"""Split-range allocations: interpolation as numpy.interp's, inverting the plant's steady lift."""

import numpy as np
import pytest
from pydrake.symbolic import Variable

from maskless.systems.control.valve_allocation import SplitRangeAllocation, current_split_allocation
from maskless.systems.plant.pneumatic_design import pneumatic_allocation
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import equilibrium_state, load_pneumatic_parameters

KNOTS = np.array([-0.01, 0.0, 0.004, 0.011, 0.018])
INLET = np.array([0.0, 0.0, 0.07, 0.12, 0.165])
OUTLET = np.array([0.165, 0.06, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def p():
    return load_pneumatic_parameters()


@pytest.mark.parametrize("knots", [[0.0, 0.0, 1.0], [0.0, 1.0, 0.5], [1.0], [[0.0, 1.0]]])
def test_rejects_non_increasing_knots(knots):
    n = np.size(knots)
    with pytest.raises(ValueError, match="command_knots"):
        SplitRangeAllocation(np.array(knots), np.zeros(n), np.zeros(n))


def test_currents_match_numpy_interp():
    allocation = SplitRangeAllocation(KNOTS, INLET, OUTLET)
    assert allocation.command_range == (-0.01, 0.018)
    commands = np.random.default_rng(0).uniform(-0.02, 0.03, 200)
    x = Variable("x")
    symbolic_inlet, symbolic_outlet = allocation.currents(x)
    for c in commands:
        inlet, outlet = allocation.currents(c)
        assert inlet == pytest.approx(np.interp(c, KNOTS, INLET), abs=1e-15)
        assert outlet == pytest.approx(np.interp(c, KNOTS, OUTLET), abs=1e-15)
        assert symbolic_inlet.Evaluate({x: c}) == pytest.approx(np.interp(c, KNOTS, INLET))
        assert symbolic_outlet.Evaluate({x: c}) == pytest.approx(np.interp(c, KNOTS, OUTLET))


def test_current_split(p):
    allocation = current_split_allocation(p.inlet, p.outlet)
    start, span = 0.060, 0.105
    for c in np.linspace(start + 1e-5, 0.165, 9):
        # Unchanged up to the 1e-6-span knot that skips the dead band.
        assert allocation.currents(c) == pytest.approx((c, 0.0), abs=2e-7)
    for c in np.linspace(start - span, start, 9):
        fraction = (start - c) / span
        expected_outlet = 0.060 + fraction * 0.105
        assert allocation.currents(c) == pytest.approx((0.0, expected_outlet), abs=1e-12)
    assert allocation.currents(start - 2 * span) == pytest.approx((0.0, 0.165))


def test_pneumatic_allocation_bottom(p):
    allocation = pneumatic_allocation(p, 0.003)
    knots = allocation.command_knots
    # The bottom knot is 3 mm below the lowest steady lift, where the outlet is fully open.
    assert knots[1] - knots[0] == pytest.approx(0.003)
    assert allocation.currents(knots[0]) == pytest.approx((0.0, 0.165))


def hammerstein_error_m(p, first_segment):
    allocation = pneumatic_allocation(p, 0.003)
    knots = allocation.command_knots
    lifts = (
        np.linspace(knots[2], knots[3], 9)
        if first_segment
        else np.linspace(knots[3], knots[-1], 25)
    )
    errors = []
    for lift in lifts:
        inlet, outlet = allocation.currents(lift)
        assert outlet == pytest.approx(0.0, abs=1e-15)
        errors.append(equilibrium_state(p, inlet, 0.0)[LIFT] - lift)
    return np.max(np.abs(errors))


def test_pneumatic_allocation_inverts_the_static_map(p):
    assert hammerstein_error_m(p, first_segment=False) < 0.2e-3


def test_pneumatic_allocation_inverts_the_first_segment(p):
    # Lift is about quadratic in current in the first segment (0-1.65 mm): a straight line there
    # misses by up to 0.4 mm, which the disturbance estimate removes in closed loop.
    assert hammerstein_error_m(p, first_segment=True) < 0.5e-3


def _hammerstein(inlet_gain_m=0.018, outlet_gain_m=-0.002):
    from maskless.systems.hammerstein_model import HammersteinModel
    from maskless.systems.plant.valve_map import ValveMap

    a = np.array([-0.9])
    return HammersteinModel(
        maps=(
            ValveMap([0.060, 0.100, 0.120, 0.165], [0.0, 0.3, 0.3, 1.0]),
            ValveMap([0.050, 0.150], [0.0, 1.0]),
        ),
        a=[a, a],
        b=[[inlet_gain_m * 0.1], [outlet_gain_m * 0.1]],
        input_delay_samples=1,
        operating_output=0.2,
        sample_period_s=0.1,
    )


def test_the_static_curve_inverse_gives_each_command_its_steady_output():
    from maskless.systems.control.valve_allocation import static_curve_inverse

    model = _hammerstein()
    allocation = static_curve_inverse(model)
    assert allocation.command_range == pytest.approx((-0.002, 0.018))
    commands = np.linspace(-0.002, 0.018, 101)
    inlet, outlet = (
        np.array([float(c) for c in currents])
        for currents in zip(*(allocation.currents(command) for command in commands), strict=True)
    )
    # Never both valves open; each command's steady output from the model's own static curves.
    opened = (inlet >= 0.060) & (outlet >= 0.050)
    assert not np.any(
        opened & (model.maps[0].opening(inlet) > 0) & (model.maps[1].opening(outlet) > 0)
    )
    steady = model.static_curve(0, inlet) + model.static_curve(1, outlet)
    # Exact but for the hair (1e-6 of the range) that separates the valves at command 0.
    np.testing.assert_allclose(steady, commands, atol=1e-7)
    # The flat run of the inlet's map is skipped: 30 % open is 100 mA, never 120 mA.
    assert allocation.currents(0.3 * 0.018)[0] == pytest.approx(0.100)


def test_a_static_curve_inverse_needs_an_inlet_that_lifts_and_an_outlet_that_lowers():
    from maskless.errors import ModelError
    from maskless.systems.control.valve_allocation import static_curve_inverse

    with pytest.raises(ModelError, match="inlet to raise the output"):
        static_curve_inverse(_hammerstein(outlet_gain_m=0.001))
