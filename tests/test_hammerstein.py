"""Hammerstein identification: exact on a planted system, and realistic on the pneumatic plant.

The planted system (known valve maps, known linear part) is the independent reference for the
estimator's exactness; the pneumatic plant, whose steady lift per current comes from its own
physics (``equilibrium_state``), is the realistic test, on a shorter record than
benchmarks/hammerstein.py measures.
"""

import dataclasses
import types

import numpy as np
import pytest
import scipy.optimize
import scipy.signal

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.hammerstein import (
    LEVELS_SCATTER_SHARE,
    _bent_section_warnings,
    _settle_samples,
    _settling_pole,
    estimate_hammerstein,
    estimate_linear_arx,
    held_out_simulation,
    minimum_samples,
    search_cost_tolerance,
)
from maskless.analysis.identification.settled_curve import settled_levels
from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.valve_level_experiment import run_two_valve_experiment
from maskless.errors import ModelError
from maskless.systems.control.valve_level_design import random_level_currents
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import equilibrium_state
from maskless.systems.plant.valve_map import ValveMap

TS = 0.1
A_TRUE = np.poly([0.95, 0.8])[1:]
# Unequal valves with curved maps, so a mix-up of inlet and outlet, or a straight map, shows.
PLANTED = HammersteinModel(
    maps=(
        ValveMap([0.060, 0.090, 0.120, 0.165], [0.0, 0.15, 0.45, 1.0]),
        ValveMap([0.050, 0.100, 0.150], [0.0, 0.6, 1.0]),
    ),
    a=[A_TRUE, A_TRUE],
    b=[[0.002, 0.001], [-0.0005, -0.0002]],
    input_delay_samples=1,
    operating_output=0.2,
    sample_period_s=TS,
    input_unit="A",
    output_unit="m",
)


def _planted_record(samples=3000, noise_m=1e-4, seed=3):
    # Independent levels: the record this test was written on. The joint search (these holds are
    # too short to settle) finds both planted starting currents within 1.5 mA on seeds 3 and 5
    # of 0-7 of this record (1 of 8 with stratified levels); on the others it misses one by
    # 6-50 mA at 98.7-99.8 % fit: a known weakness of the joint search, not asserted away.
    currents = random_level_currents(samples, TS, (0.19, 0.19), (0.5, 4.0), seed, stratified=False)
    u = currents.T
    rng = np.random.default_rng(seed)
    return u, PLANTED.simulate(u) + noise_m * rng.standard_normal(samples)


@pytest.fixture(scope="module")
def planted_fit():
    u, y = _planted_record()
    return u, y, estimate_hammerstein(u, y, 2, TS, input_unit="A", output_unit="m")


def test_the_planted_maps_poles_and_gains_are_recovered(planted_fit):
    _, _, fit = planted_fit
    model = fit.model
    assert fit.converged, fit.message
    for estimated, true in zip(model.maps, PLANTED.maps, strict=True):
        assert estimated.starting_current == pytest.approx(true.starting_current, abs=1.5e-3)
        assert estimated.saturation_current == pytest.approx(true.saturation_current, abs=1.5e-3)
    np.testing.assert_allclose(np.sort(model.poles().real), [0.8, 0.95], atol=5e-3)
    currents = np.linspace(0.0, 0.19, 191)
    for valve in range(2):
        truth = PLANTED.static_curve(valve, currents)
        error = np.max(np.abs(model.static_curve(valve, currents) - truth))
        assert error < 0.03 * np.max(np.abs(truth))
    assert model.operating_output == pytest.approx(0.2, abs=1e-3)


def test_the_planted_fit_simulates_held_out_data_and_beats_linear_models(planted_fit):
    u, y, fit = planted_fit
    assert fit.simulation_fit_percent > 98.5
    assert fit.simulation_fit_percent >= fit.start_fit_percent
    u_new, y_new = _planted_record(1500, seed=4)
    hammerstein = fit_percent(y_new, fit.model.simulate(u_new))
    output_error = estimate_hammerstein(u, y, 2, TS, linear=True).model
    arx = estimate_linear_arx(u, y, 4, TS)
    assert hammerstein > 98.0
    for linear in (output_error, arx):
        assert hammerstein > fit_percent(y_new, linear.simulate(u_new)) + 20.0


def test_a_held_out_part_is_judged_in_the_state_the_model_reached_not_from_rest():
    # A step of the inlet to 0.15 A: the part held out opens 2 s later, while the head is
    # still rising (the slow pole, 0.95 at 0.1 s, settles in some 10 s).
    u = np.zeros((400, 2))
    u[100:, 0] = 0.15
    y = PLANTED.simulate(u)
    part = slice(120, None)
    # The planted model itself, noise-free: simulated from the record's start it is the record.
    np.testing.assert_allclose(held_out_simulation(PLANTED, u, part), y[part], rtol=0, atol=1e-12)
    assert fit_percent(y[part], held_out_simulation(PLANTED, u, part)) == pytest.approx(100.0)
    # From rest at the part's first currents, the same model starts at its settled output and
    # scores far below: the figure would judge where the split fell.
    assert fit_percent(y[part], PLANTED.simulate(u[part])) < 50.0


def test_the_same_record_gives_the_same_model_bit_for_bit(planted_fit):
    u, y, fit = planted_fit
    again = estimate_hammerstein(u, y, 2, TS, input_unit="A", output_unit="m").model
    np.testing.assert_array_equal(again.a, fit.model.a)
    np.testing.assert_array_equal(again.b, fit.model.b)
    np.testing.assert_array_equal(again.maps[0].currents, fit.model.maps[0].currents)


def test_the_summary_reports_each_valve_and_the_poles(planted_fit):
    summary = planted_fit[2].summary()
    assert set(summary["valves"]) == {"inlet", "outlet"}
    inlet = summary["valves"]["inlet"]
    assert inlet["starting_current"] == pytest.approx(0.060, abs=1.5e-3)
    assert inlet["curve_outputs"][-1] == pytest.approx(inlet["dc_gain"])
    assert len(summary["poles"]) == 2
    assert summary["warnings"] == list(planted_fit[2].warnings)
    # The report's fields come from the summary, not added beside it by the command.
    u, _, fit = planted_fit
    for index, valve in enumerate(summary["valves"].values()):
        assert valve["starting_current_spread"] == list(fit.starting_current_spread()[index])
        assert valve["spread_cost_tolerance"] == fit.search_tolerance > 0.0
        assert valve["highest_current_in_record"] == pytest.approx(u[:, index].max())
    # The spread holds the planted start. How wide it is depends on where the other searches
    # end, and that on the CPU's rounding: on one machine every search about as good found the
    # inlet's 60 mA, on another (AMD EPYC, 2026-11-24) one ended at 34.2 mA with a cost 0.35 %
    # above the best, inside the spread's tolerance (8.1 % there: search_cost_tolerance).
    for (low, high), true in zip(
        planted_fit[2].starting_current_spread(), PLANTED.maps, strict=True
    ):
        assert low - 1.5e-3 < true.starting_current < high + 1.5e-3


def test_maps_from_the_joint_search_are_named_with_the_holds_that_would_settle(planted_fit):
    # The planted record's holds (0.5-4 s) end long before its slowest pole (0.95 at 0.1 s:
    # 4 time constants are 7.8 s) settles, so no settled level reads the curves.
    (warning,) = planted_fit[2].warnings
    assert warning.startswith("too few holds settled to read the static curves")
    assert "the spread lists those ends, not an interval" in warning
    advised_s = float(warning.split("hold levels at least ")[1].split(" s")[0])
    # Holds of the advised length settle on the planted plant (the ARX pole reads 0.944).
    assert advised_s > 4.0 * TS / -np.log(0.95)
    # Over twice the record, so that as many of them settle; the figure is the fit's own.
    assert "in an experiment twice as long as this one" in warning
    assert planted_fit[2].advised_hold_s == pytest.approx(advised_s, abs=0.5)
    assert planted_fit[2].summary()["advised_hold_s"] == planted_fit[2].advised_hold_s
    assert planted_fit[2].summary()["valves"]["inlet"]["starting_current_from"] == (
        "the joint search"
    )
    # A joint search reads no saturation's interval.
    assert planted_fit[2].summary()["valves"]["inlet"]["saturation_current_spread"] is None


def test_the_search_cost_tolerance_counts_the_independent_samples_in_the_errors():
    # A likelihood-ratio test for one parameter: N' log(V / V_best) <= chi2(1, 0.95) = 3.841,
    # N' the samples over their integrated autocorrelation time, (1 + rho) / (1 - rho) for an
    # AR(1) sequence (a closed form).
    rng = np.random.default_rng(11)
    # Long enough that the estimate's own scatter (about 5 % here) stays inside the tolerance.
    samples = 100_000
    white = rng.standard_normal(samples)
    assert search_cost_tolerance(white) == pytest.approx(np.expm1(3.841 / samples), rel=0.1)
    rho = 0.9
    correlated = scipy.signal.lfilter([1.0], [1.0, -rho], white)
    expected = np.expm1(3.841 * (1 + rho) / (1 - rho) / samples)
    assert search_cost_tolerance(correlated) == pytest.approx(expected, rel=0.15)


def test_the_spread_holds_the_searches_within_the_fits_tolerance(planted_fit):
    fit = dataclasses.replace(
        planted_fit[2],
        start_intervals=(),
        searches=((1.0, (0.060, 0.050)), (1.02, (0.052, 0.051)), (1.2, (0.030, 0.090))),
        search_tolerance=0.05,
    )
    assert fit.starting_current_spread() == [(0.052, 0.060), (0.050, 0.051)]
    narrow = dataclasses.replace(fit, search_tolerance=0.01)
    assert narrow.starting_current_spread() == [(0.060, 0.060), (0.050, 0.050)]


def test_the_summary_names_where_each_start_came_from(planted_fit):
    fit = planted_fit[2]
    joint = fit.summary()["valves"]["inlet"]
    assert joint["starting_current_from"] == "the joint search" and joint["play_half_width"] is None
    sectioned = dataclasses.replace(
        fit,
        start_intervals=((0.05, 0.07), (0.04, 0.06)),
        play_half_widths=(0.001, 0.0025),
        starts_from_sections=(False, True),
    ).summary()["valves"]
    assert sectioned["inlet"]["starting_current_from"] == "the settled levels"
    assert sectioned["inlet"]["play_half_width"] == 0.001
    assert sectioned["outlet"]["starting_current_from"].startswith("a section")
    assert sectioned["outlet"]["play_half_width"] == 0.0025
    assert sectioned["outlet"]["starting_current_spread"] == [0.04, 0.06]
    assert "bent" not in sectioned["outlet"]["starting_current_from"]
    bent = dataclasses.replace(
        fit,
        start_intervals=((0.05, 0.07), (0.04, 0.06)),
        starts_from_sections=(False, True),
        starts_from_bent_sections=(False, True),
    ).summary()["valves"]["outlet"]["starting_current_from"]
    assert bent.startswith("a section") and bent.endswith("its hinge bent once above the start")


def test_a_section_read_two_ways_that_do_not_meet_is_warned():
    curves = types.SimpleNamespace(
        starts=np.array([0.06, 0.0604]),
        straight_section_starts=(None, 0.0765),
        sections_read_apart=(False, True),
    )
    (warning,) = _bent_section_warnings(curves, "A")
    assert warning.startswith("outlet: its section reads the start at 0.0604 A")
    assert "at 0.0765 A straight" in warning and "cannot tell" in warning
    meeting = types.SimpleNamespace(**{**vars(curves), "sections_read_apart": (False, False)})
    assert _bent_section_warnings(meeting, "A") == ()


def test_a_search_stopped_early_is_named_not_raised():
    u, y = _planted_record(1000)
    fit = estimate_hammerstein(u, y, 2, TS, max_evaluations=3)
    assert not fit.converged
    assert fit.message.startswith(("not converged", "search failed"))
    assert np.isfinite(fit.simulation_fit_percent)


def test_a_search_that_raises_returns_its_start_named_as_failed(monkeypatch):
    def raising(*args, **kwargs):
        raise ValueError("Residuals are not finite in the initial point.")

    monkeypatch.setattr(scipy.optimize, "least_squares", raising)
    u, y = _planted_record(1000)
    fit = estimate_hammerstein(u, y, 2, TS)
    assert not fit.converged and fit.searches == ()
    assert fit.message == "search failed: Residuals are not finite in the initial point."
    assert fit.simulation_fit_percent == fit.start_fit_percent


@pytest.mark.parametrize("trust_region", ["ends lower", "raises"])
def test_a_search_stopped_where_a_reflection_saturates_is_searched_again_by_trust_region(
    trust_region, monkeypatch
):
    # Levenberg-Marquardt ends with A(q)'s second reflection coefficient at tanh(-25) = -1 (the
    # poles at +-r: it stopped where tanh is flat); the trust-region search from the same start
    # ends lower and is kept. Should it raise, the stuck end still counts as a search's end. An
    # end with no reflection saturated is not searched again.
    real = scipy.optimize.least_squares
    methods = []

    def recording(fun, x0, **kwargs):
        methods.append(kwargs["method"])
        if kwargs["method"] == "trf" and trust_region == "raises":
            raise ValueError("Residuals are not finite in the initial point.")
        found = real(fun, x0, **kwargs)
        if kwargs["method"] == "lm" and len(methods) == 1:
            stuck = found.x.copy()
            stuck[:2] = [3.5, -25.0]
            return scipy.optimize.OptimizeResult(
                x=stuck, cost=found.cost * 2.0, status=2, nfev=5, message="stuck"
            )
        return found

    monkeypatch.setattr(scipy.optimize, "least_squares", recording)
    u, y = _planted_record(1000)
    fit = estimate_hammerstein(u, y, 2, TS)
    assert methods[:2] == ["lm", "trf"] and methods.count("trf") == 1
    assert len(fit.searches) == methods.count("lm")  # every start ended somewhere
    # The planted poles (0.95, 0.8), not the stuck end's +-r.
    poles = np.sort(np.roots(np.r_[1.0, fit.model.a[0]]))
    np.testing.assert_allclose(poles, [0.8, 0.95], atol=0.02)


@pytest.mark.parametrize(
    "change, message",
    [
        ({"u": np.zeros((500, 2))}, "u column 0 is constant"),
        ({"y": np.full(1000, 0.2)}, "y is constant"),
        ({"y": np.zeros(999)}, r"u must be \(N, inputs\) and y \(N,\) of one length"),
        ({"order": 0}, "order = 0: expected an integer >= 1"),
        ({"map_segments": 2.5}, "map_segments = 2.5"),
        ({"input_delay_samples": 0}, "input_delay_samples = 0"),
        ({"u": np.full((1000, 2), np.nan)}, "u and y must be finite"),
        ({"sample_period_s": -0.1}, "sample_period_s = -0.1"),
    ],
)
def test_bad_arguments_are_one_line_naming_the_argument(change, message):
    u, y = _planted_record(1000)
    arguments = {"u": u, "y": y, "order": 2, "sample_period_s": TS, **change}
    if "u" in change and arguments["u"].shape[0] != y.size:
        arguments["y"] = y[: arguments["u"].shape[0]]
    with pytest.raises(ValueError, match=message):
        estimate_hammerstein(**arguments)


def test_a_valve_never_opened_but_for_rounding_is_refused_as_constant():
    # A closed loop's record: its outlet at 0 A but for one sample of 1.4e-17 A. Before, that
    # sample passed for variation and the fit made up the outlet's map.
    u, y = _planted_record(1000)
    u[:, 1] = 0.0
    u[0, 1] = 1.4e-17
    with pytest.raises(ValueError, match="u column 1 is constant"):
        estimate_hammerstein(u, y, 2, TS)


def test_too_few_samples_are_refused_with_the_count_the_parameters_take():
    u, y = _planted_record(1000)
    # Order 2, two valves of 6 segments: 2 + 2 * (2 + 6 + 1) + 1 = 21 parameters, 10 samples each.
    assert minimum_samples(2, 2) == 210
    with pytest.raises(ValueError, match="209 samples are too few: at least 210 "):
        estimate_hammerstein(u[:209], y[:209], 2, TS)


def test_the_model_simulates_as_its_state_space_and_settles_at_its_static_curve():
    u, _ = _planted_record(400)
    A, B, C = PLANTED.state_space()
    openings = PLANTED.openings(u)
    steady = np.linalg.solve(np.eye(A.shape[0]) - A, B @ openings[0])
    x, expected = steady, []
    for opening in openings:
        expected.append(PLANTED.operating_output + (C @ x)[0])
        x = A @ x + B @ opening
    np.testing.assert_allclose(PLANTED.simulate(u), expected, atol=1e-12)
    # The DC gain against scipy's own transfer function at z = 1.
    numerator, denominator = PLANTED.numerators()[0], np.concatenate([[1.0], PLANTED.a[0]])
    _, response = scipy.signal.freqz(numerator, denominator, worN=[0.0])
    assert PLANTED.dc_gains()[0] == pytest.approx(response[0].real)


def test_a_valve_linear_model_has_unit_dc_gain_and_the_valves_poles():
    model = PLANTED.valve_linear_model(1)
    assert model.dc_gain() == pytest.approx(1.0)
    np.testing.assert_allclose(np.sort(model.poles().real), [0.8, 0.95])


@pytest.mark.parametrize(
    "poles, delay",
    [
        ([0.95, 0.8], 1),
        ([0.95, 0.8], 3),
        ([0.9 * np.exp(0.3j), 0.9 * np.exp(-0.3j), 0.7], 2),
        ([0.9, 0.9], 1),
    ],
    ids=["real", "delayed", "complex-pair", "repeated"],
)
def test_a_valve_linear_model_is_the_valves_transfer_function_with_its_modes_as_states(
    poles, delay
):
    a = np.real(np.poly(poles))[1:]
    b = np.array([0.002, -0.001, 0.0005])[: a.size]
    model = dataclasses.replace(PLANTED, a=[a, a], b=[b, b], input_delay_samples=delay)
    linear = model.valve_linear_model(0)
    # Against scipy's frequency response of q^-d B(q) / A(q), per unit DC gain.
    omega = np.linspace(0.01, 3.0, 7)
    numerator = np.concatenate([np.zeros(delay), b]) / model.dc_gains()[0]
    _, expected = scipy.signal.freqz(numerator, np.concatenate([[1.0], a]), worN=omega)
    np.testing.assert_allclose(linear.transfer_function(np.exp(1j * omega)), expected, rtol=1e-9)
    # Past the d - 1 delayed inputs, each state is a mode: the dynamics are block diagonal, one
    # block per real pole or complex pair (a repeated pole keeps the observer form).
    modes = linear.A[delay - 1 :, delay - 1 :]
    if len(set(poles)) == len(poles):
        complex_pairs = sum(np.imag(pole) > 0 for pole in poles)
        assert np.count_nonzero(modes - np.diag(np.diag(modes))) == 2 * complex_pairs
    np.testing.assert_allclose(
        np.sort_complex(np.linalg.eigvals(modes)), np.sort_complex(np.array(poles)), atol=1e-6
    )


@pytest.mark.parametrize(
    "change, message",
    [
        ({"a": [[0.1], [0.1]]}, r"b must have shape \(2, 1\)"),
        ({"a": [0.1, 0.2]}, r"a must have shape \(2, n >= 1\)"),
        ({"b": [[np.inf, 0.0], [0.0, 0.0]]}, "a and b must be finite"),
        ({"input_delay_samples": 0}, "input_delay_samples = 0"),
        ({"sample_period_s": 0.0}, "sample_period_s = 0.0: expected > 0"),
        ({"maps": ()}, "maps must be one or more ValveMap"),
    ],
)
def test_a_bad_model_is_refused_naming_the_field(change, message):
    fields = {
        "maps": PLANTED.maps,
        "a": PLANTED.a,
        "b": PLANTED.b,
        "input_delay_samples": 1,
        "operating_output": 0.2,
        "sample_period_s": TS,
        **change,
    }
    with pytest.raises(ModelError, match=message):
        HammersteinModel(**fields)


# --- the pneumatic plant ---------------------------------------------------------------------

# The record of benchmarks/hammerstein.py (its defaults: an hour, stratified levels held 5-60 s,
# seed 0; the design reads no starting current, the idle valve is shut), where it measured
# (currents in mA): the inlet's static curve within 2.9 % of full scale, its starting current at
# 58.4 (the plant's: 60), and 24.7 points of held-out simulation fit over the best linear model.
# The curves read the valves' play (``settled_curve``) but the model runs none: its map is the
# curve at the middle of the band. Against the map fitted without the play (start 63.0), the
# held-out fit fell from 80.3 to 79.7 % and the margin over this test's linear model from 25.3
# to 24.7 points; the bound below keeps 4.7 points of that.
# The two-stage fit reads the curve from the holds that settled; an hour is the shortest record
# that puts some fifteen settled levels on each valve.
PNEUMATIC_DURATION_S = 3600.0


@pytest.fixture(scope="module")
def pneumatic_record():
    config = load_scenario()
    period_s = config.offset_free_lqg.sample_period_s
    samples = round(PNEUMATIC_DURATION_S / period_s)
    currents = random_level_currents(samples, period_s, (0.19, 0.19), (5, 60), 0)
    applied, height_m, _ = run_two_valve_experiment(config, currents, period_s)
    return config, period_s, applied.T, height_m


@pytest.fixture(scope="module")
def pneumatic_fit(pneumatic_record):
    _, period_s, u, y = pneumatic_record
    split = round(0.7 * y.size)
    return split, estimate_hammerstein(u[:split], y[:split], 2, period_s, output_unit="m")


def test_on_the_pneumatic_plant_the_inlet_curve_is_found_and_beats_linear_models(
    pneumatic_record, pneumatic_fit
):
    config, period_s, u, y = pneumatic_record
    split, fit = pneumatic_fit
    model = fit.model
    p = config.pneumatic
    working = np.linspace(p.inlet.starting_current_a, p.inlet.saturation_current_a, 50)
    truth = [equilibrium_state(p, i, 0.0)[LIFT] for i in working]
    error = np.max(np.abs(model.static_curve(0, working) - truth))
    assert error < 0.10 * np.max(truth)  # issue 14's target
    assert model.maps[0].starting_current == pytest.approx(p.inlet.starting_current_a, abs=5e-3)
    low, high = fit.starting_current_spread()[0]
    assert low <= p.inlet.starting_current_a <= high
    # No pole next to 1: with the curves fixed, the search once put one at 0.9999 with a zero all
    # but cancelling it (a slow drift the offset-free design creeps on, or refuses).
    assert np.max(np.abs(model.poles())) < 0.995
    assert model.valve_linear_model(0).dc_gain() == pytest.approx(1.0)
    hammerstein = fit_percent(y[split:], model.simulate(u[split:]))
    linear = estimate_hammerstein(u[:split], y[:split], 2, period_s, linear=True).model
    assert hammerstein > fit_percent(y[split:], linear.simulate(u[split:])) + 20.0


def test_levels_moved_by_something_the_valves_do_not_drive_are_named(
    pneumatic_record, pneumatic_fit
):
    # The standard population's patient shifts (assets/presets/patient_motion.yaml: steps of
    # 1 mm standard deviation, one every 2 min on average) added to the still record: a random
    # walk of the head the valves do not drive. The still record's levels stay on the curves.
    _, period_s, u, y = pneumatic_record
    split, still = pneumatic_fit
    rng = np.random.default_rng(0)
    shifts = (rng.random(y.size) < period_s / 120.0) * rng.normal(0.0, 1e-3, y.size)
    moved = estimate_hammerstein(
        u[:split], (y + np.cumsum(shifts))[:split], 2, period_s, output_unit="m"
    )
    for fit, wanders in ((still, False), (moved, True)):
        full_scale = np.max(np.abs(fit.model.dc_gains()))
        assert (fit.levels_scatter > LEVELS_SCATTER_SHARE * full_scale) == wanders
        named = [w for w in fit.warnings if w.startswith("the settled levels scatter")]
        assert len(named) == wanders
        assert fit.summary()["levels_scatter"] == fit.levels_scatter
    # The still levels scatter by the cameras' noise averaged over a hold (0.45 mm a frame).
    assert still.levels_scatter < 2e-4


def test_through_the_maps_the_arx_model_settles_as_the_planted_plant_where_a_linear_one_is_slow():
    # Split-range holds of 7.5-90 s (0.1 s samples) through a dead zone and a bent map per
    # valve, poles 0.97 and 0.8: a linear ARX model makes up for the maps with a slower pole.
    rng = np.random.default_rng(0)
    holds, levels = rng.integers(75, 900, 80), rng.uniform(0.0, 1.0, (80, 2))
    levels[::2, 1], levels[1::2, 0] = 0.0, 0.0
    u = np.repeat(levels, holds, axis=0)
    opening = np.clip((u - 0.35) / 0.65, 0.0, 1.0)
    a = np.poly([0.97, 0.8])
    y = scipy.signal.lfilter([0.0, a.sum()], a, opening[:, 0] ** 2 - 0.3 * np.sqrt(opening[:, 1]))
    y += 0.005 * rng.standard_normal(y.size)
    linear, mapped = (_settling_pole(u, y, 2, 6, 1, maps) for maps in (False, True))
    assert abs(mapped - 0.97) < 0.01 and linear > 0.99
    # Four time constants of the linear pole outlast more of the holds: 41 settle, not 68.
    counts = [
        settled_levels(u, y, _settle_samples(pole), _settle_samples(pole) // 8).outputs.size
        for pole in (linear, mapped)
    ]
    assert counts[1] > 1.5 * counts[0]
