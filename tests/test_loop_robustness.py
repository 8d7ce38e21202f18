"""Loop robustness: each margin checked by closing the loop at its edge; loop gain against scipy."""

import dataclasses
import math

import numpy as np
import pytest
import scipy.signal

from maskless.analysis.stability.loop_robustness import (
    analyze_loop,
    analyze_paper_loop,
    command_holding_lift_m,
    holdable_lift_range_m,
    loop_gain_peak,
    plant_at_lift,
    robustness_cases,
    steady_lift_at_command_m,
)
from maskless.analysis.stability.margins import added_delay_samples_loop, feedback_loop_poles
from maskless.diagrams.plant_analysis import offset_free_setup
from maskless.diagrams.scenario import load_scenario
from maskless.systems.control.offset_free_lqg import controller_state_space
from maskless.systems.control.paper_lqg import paper_lqg
from maskless.systems.linear_model import LinearModel


@pytest.fixture(scope="module")
def config():
    return load_scenario()


@pytest.fixture(scope="module")
def paper(config):
    model, design = paper_lqg(config.paper)
    return model, analyze_paper_loop(model, design)


@pytest.fixture(scope="module")
def setup(config):
    return offset_free_setup(config)


@pytest.fixture(scope="module")
def nominal_loop(config, setup):
    """The offset-free loop at its operating lift, 9 mm, nominal head, designed delay."""
    _, allocation, design = setup
    plant, _ = plant_at_lift(
        config.pneumatic,
        allocation,
        0.009,
        design.model.sample_period_s,
        design.measurement_delay_samples,
    )
    return analyze_loop(plant, controller_state_space(design))


def sorted_poles(poles):
    return np.array(sorted(np.asarray(poles), key=lambda z: (round(z.real, 9), z.imag)))


def test_paper_loop_poles_are_regulator_and_estimator_poles(paper):
    _, result = paper
    # Separation principle: the LQG loop's poles are eig(A - BK) and eig(A - LC).
    expected = np.concatenate([result.regulator_poles, result.estimator_poles])
    np.testing.assert_allclose(
        sorted_poles(result.loop.poles), sorted_poles(expected), rtol=0, atol=1e-9
    )
    assert result.loop.stable


def test_paper_loop_is_nearly_open(paper):
    model, result = paper
    # B ~ 1e-7 mm/mA: the regulator leaves the plant's poles where they were, and the loop gain
    # stays tiny at every frequency, so feedback cannot change the response.
    assert result.regulator_pole_shift < 1e-6
    np.testing.assert_allclose(
        sorted_poles(result.open_loop_poles), sorted_poles(np.linalg.eigvals(model.A))
    )
    assert result.peak_loop_gain < 1e-4
    assert math.isinf(result.loop.margins.phase_margin_deg)
    # |L| at the -180° crossing is at most its peak.
    assert result.loop.margins.gain_margin >= (1.0 - 1e-9) / result.peak_loop_gain


def test_loop_gain_peak_matches_scipy_frequency_response(paper):
    _, result = paper
    loop = result.loop
    # Independent path: the plant's and controller's transfer functions by scipy, multiplied.
    plant_num, plant_den = scipy.signal.ss2tf(
        loop.plant.A, loop.plant.B, loop.plant.C, loop.plant.D
    )
    ctrl = loop.controller
    ctrl_num, ctrl_den = scipy.signal.ss2tf(ctrl.A, ctrl.B, ctrl.C, ctrl.D)
    ts = loop.plant.sample_period_s
    omega = np.geomspace(1e-6 * math.pi / ts, math.pi / ts, 200_000)
    _, g = scipy.signal.freqz(plant_num[0], plant_den, worN=omega * ts)
    _, k = scipy.signal.freqz(ctrl_num[0], ctrl_den, worN=omega * ts)
    magnitude = np.abs(k * g)
    best = int(np.argmax(magnitude))
    assert result.peak_loop_gain == pytest.approx(magnitude[best], rel=1e-6)
    assert result.peak_loop_gain_frequency_rad_s == pytest.approx(omega[best], rel=1e-3)


def test_loop_gain_peak_of_a_first_order_lag_is_at_dc():
    # L(z) = b / (z - a): |L| is largest at z = 1, b / (1 - a); the grid starts just above it.
    loop = LinearModel([[0.5]], [[1.0]], [[0.25]], [[0.0]], 0.1)
    peak, frequency = loop_gain_peak(loop)
    assert peak == pytest.approx(0.5, rel=1e-9)
    assert frequency < 1e-3


def scaled(controller, factor):
    return LinearModel(
        controller.A,
        controller.B,
        factor * controller.C,
        factor * controller.D,
        controller.sample_period_s,
    )


@pytest.mark.parametrize("which", ["paper", "offset_free"])
def test_gain_margin_puts_a_closed_loop_pole_on_the_unit_circle(which, paper, nominal_loop):
    analysis = paper[1].loop if which == "paper" else nominal_loop
    margins = analysis.margins
    poles = feedback_loop_poles(analysis.plant, scaled(analysis.controller, margins.gain_margin))
    critical = poles[np.argmax(np.abs(poles))]
    assert abs(critical) == pytest.approx(1.0, abs=1e-9)
    ts = analysis.plant.sample_period_s
    assert abs(np.angle(critical)) == pytest.approx(margins.phase_crossover_rad_s * ts, rel=1e-6)
    # A little less gain is stable, a little more is not.
    for factor, is_stable in ((0.99, True), (1.01, False)):
        poles = feedback_loop_poles(
            analysis.plant, scaled(analysis.controller, factor * margins.gain_margin)
        )
        assert bool(np.all(np.abs(poles) < 1)) is is_stable


def test_delay_margin_bounds_the_stable_whole_tick_latencies(nominal_loop):
    margins = nominal_loop.margins
    ts = nominal_loop.plant.sample_period_s
    ticks = math.floor(margins.delay_margin_s / ts)
    for extra, is_stable in ((ticks, True), (ticks + 1, False)):
        poles = feedback_loop_poles(
            added_delay_samples_loop(nominal_loop.plant, extra), nominal_loop.controller
        )
        assert bool(np.all(np.abs(poles) < 1)) is is_stable


def test_extra_latency_costs_phase_at_crossover_and_nothing_else(config, setup):
    _, allocation, design = setup
    cases = robustness_cases(config.pneumatic, allocation, design, [0.005], [1.0], [0, 1, 2])
    base = cases[0].analysis.margins
    ts = design.model.sample_period_s
    for case in cases[1:]:
        m = case.analysis.margins
        # A pure delay leaves |L| alone and lags it by ω d Ts.
        assert m.gain_crossover_rad_s == pytest.approx(base.gain_crossover_rad_s, rel=1e-9)
        lag_deg = math.degrees(base.gain_crossover_rad_s * case.extra_delay_samples * ts)
        assert m.phase_margin_deg == pytest.approx(base.phase_margin_deg - lag_deg, abs=1e-6)
        assert case.analysis.poles.size == cases[0].analysis.poles.size + case.extra_delay_samples
        assert case.extra_delay_s == pytest.approx(case.extra_delay_samples * ts)


def test_holding_command_inverts_the_nominal_head_and_offsets_a_heavy_one(config, setup):
    nominal, allocation, _ = setup
    heavy = dataclasses.replace(nominal, head_mass_kg=1.2 * nominal.head_mass_kg)
    # The heavier head rests lower by its extra weight over the fabric stiffness at any pressure.
    sag_m = (heavy.head_mass_kg - nominal.head_mass_kg) * heavy.gravity_m_s2 / heavy.stiffness_n_m
    for lift in (0.002, 0.009, 0.013):
        command = command_holding_lift_m(nominal, allocation, lift)
        # The allocation is the nominal static map's piecewise-linear inverse (12 knots).
        assert command == pytest.approx(lift, abs=1e-4)
        assert steady_lift_at_command_m(nominal, allocation, command) == pytest.approx(lift)
        heavy_command = command_holding_lift_m(heavy, allocation, lift)
        assert heavy_command - command == pytest.approx(sag_m, abs=1e-4)


@pytest.mark.parametrize(
    "lift_m, valve",
    [(0.009, "inlet"), (-0.001, "outlet")],  # below zero lift only the outlet holds the head
)
def test_plant_dc_gain_is_the_slope_of_steady_lift_per_command(config, setup, lift_m, valve):
    nominal, allocation, design = setup
    plant, point = plant_at_lift(nominal, allocation, lift_m, design.model.sample_period_s, 3)
    assert point.valves.valve == valve and point.lift_m == lift_m
    assert plant.order == 4 + 3
    dc_gain = plant.dc_gain()
    h = 1e-6
    slope = (
        steady_lift_at_command_m(nominal, allocation, point.command_m + h)
        - steady_lift_at_command_m(nominal, allocation, point.command_m - h)
    ) / (2 * h)
    assert dc_gain == pytest.approx(slope, rel=1e-4)


def test_default_cases_are_stable_with_margins(config, setup):
    _, allocation, design = setup
    cases = robustness_cases(
        config.pneumatic, allocation, design, [0.002, 0.013], [0.8, 1.2], [0, 1]
    )
    assert [(c.lift_m, c.mass_factor, c.extra_delay_samples) for c in cases] == [
        (lift, factor, extra)
        for lift in (0.002, 0.013)
        for factor in (0.8, 1.2)
        for extra in (0, 1)
    ]
    for case in cases:
        assert case.head_mass_kg == pytest.approx(case.mass_factor * config.pneumatic.head_mass_kg)
        assert case.analysis.stable
        assert case.analysis.max_pole_magnitude == pytest.approx(
            np.max(np.abs(case.analysis.poles))
        )
    # The light head rests above 2 mm with both valves shut: the outlet holds it there.
    assert cases[0].operating_point.valves.valve == "outlet"


def test_holdable_range_is_the_allocations_ends(setup):
    nominal, allocation, _ = setup
    low, high = holdable_lift_range_m(nominal, allocation)
    assert low < 0.0 < high
    with pytest.raises(ValueError, match="lift_m = 0.05"):
        command_holding_lift_m(nominal, allocation, 0.05)
    with pytest.raises(ValueError, match="lift_m"):
        command_holding_lift_m(nominal, allocation, low - 1e-4)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"mass_factors": [0.0]}, "mass_factors"),
        ({"mass_factors": [float("nan")]}, "mass_factors"),
        ({"extra_delays_samples": [-1]}, "extra_delays_samples"),
        ({"extra_delays_samples": [0.5]}, "extra_delays_samples"),
        ({"lifts_m": [0.05]}, "lift_m = 0.05"),
    ],
)
def test_bad_case_arguments_are_refused(config, setup, kwargs, match):
    _, allocation, design = setup
    arguments = {"lifts_m": [0.009], "mass_factors": [1.0], "extra_delays_samples": [0]}
    arguments.update(kwargs)
    with pytest.raises(ValueError, match=match):
        robustness_cases(config.pneumatic, allocation, design, **arguments)
