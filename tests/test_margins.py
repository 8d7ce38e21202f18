"""Stability margins against closed forms, scipy and the closed-loop poles at each margin's edge."""

import json
import math

import numpy as np
import pytest
import scipy.linalg
import scipy.signal

from maskless.analysis.stability.margins import (
    Margins,
    added_delay_samples_loop,
    discrete_margins,
    feedback_loop_poles,
    loop_transfer,
    series,
)
from maskless.systems.linear_model import LinearModel, stable

TS = 0.048


def integrator(sample_period_s):
    """G(z) = Ts / (z - 1): forward-Euler integration of u."""
    return LinearModel([[1.0]], [[sample_period_s]], [[1.0]], [[0.0]], sample_period_s)


def random_model(seed, n, feedthrough=0.0):
    """A stable SISO model with n states and well-spread poles."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))
    return LinearModel(A, rng.normal(size=(n, 1)), rng.normal(size=(1, n)), [[feedthrough]], TS)


def lqg_loop():
    """A lightly damped lag plus integrator, and the observer-based LQG controller.

    The controller is x̂(k+1) = (A - B Kx - Lk C) x̂ + Lk y, u = -Kx x̂, whose output carries its
    minus sign.
    """
    A = np.array([[1.0, TS], [0.0, 0.9]])
    B = np.array([[0.0], [TS]])
    C = np.array([[1.0, 0.0]])
    P = scipy.linalg.solve_discrete_are(A, B, np.diag([100.0, 1.0]), np.array([[0.01]]))
    Kx = np.linalg.solve(0.01 + B.T @ P @ B, B.T @ P @ A)
    S = scipy.linalg.solve_discrete_are(A.T, C.T, np.diag([1e-4, 1e-2]), np.array([[1e-4]]))
    Lk = A @ S @ C.T / (C @ S @ C.T + 1e-4)
    plant = LinearModel(A, B, C, [[0.0]], TS)
    controller = LinearModel(A - B @ Kx - Lk @ C, Lk, -Kx, [[0.0]], TS)
    return plant, controller, (A - B @ Kx, A - Lk @ C)


def scaled(model, factor):
    return LinearModel(model.A, model.B, factor * model.C, factor * model.D, TS)


def sorted_poles(poles):
    return np.sort_complex(np.round(np.asarray(poles, complex), 10))


# Integrator loop L(z) = k Ts / (z - 1): ∠L = -90° - ωTs/2 and |L| = k Ts / (2 sin(ωTs/2)).
@pytest.mark.parametrize(
    "gain, sample_period_s", [(5.0, TS), (10.0, 0.01), (30.0, 0.05), (1.0, 1.0)]
)
def test_integrator_loop_margins_match_the_closed_form(gain, sample_period_s):
    kT = gain * sample_period_s
    plant = integrator(sample_period_s)
    controller = LinearModel.static_gain(-gain, sample_period_s)

    np.testing.assert_allclose(feedback_loop_poles(plant, controller), [1.0 - kT], atol=1e-14)
    margins = discrete_margins(loop_transfer(plant, controller))

    # The phase reaches -180° only at Nyquist, where |L| = kT / 2.
    assert margins.gain_margin == pytest.approx(2.0 / kT, rel=1e-12)
    assert margins.gain_margin_db == pytest.approx(20 * math.log10(2.0 / kT), rel=1e-12)
    assert margins.phase_crossover_rad_s == pytest.approx(math.pi / sample_period_s, rel=1e-12)
    crossover = 2.0 / sample_period_s * math.asin(kT / 2.0)
    phase_margin_deg = 90.0 - math.degrees(crossover * sample_period_s / 2.0)
    assert margins.gain_crossover_rad_s == pytest.approx(crossover, rel=1e-9)
    assert margins.phase_margin_deg == pytest.approx(phase_margin_deg, rel=1e-9)
    assert margins.delay_margin_s == pytest.approx(
        math.radians(phase_margin_deg) / crossover, rel=1e-9
    )


def test_the_sign_argument_closes_the_loop_around_a_controller_without_its_minus_sign():
    plant = integrator(TS)
    written_with_sign = LinearModel.static_gain(-5.0, TS)
    written_without = LinearModel.static_gain(5.0, TS)
    np.testing.assert_allclose(
        feedback_loop_poles(plant, written_without, sign=-1),
        feedback_loop_poles(plant, written_with_sign),
    )
    omega = np.linspace(1.0, 60.0, 7)
    np.testing.assert_allclose(
        loop_transfer(plant, written_without, sign=-1).frequency_response(omega),
        loop_transfer(plant, written_with_sign).frequency_response(omega),
    )


def test_series_multiplies_responses_and_unites_poles():
    first, second = random_model(1, 3, 0.2), random_model(2, 2, -0.5)
    cascade = series(first, second)
    omega = np.geomspace(0.1, 60.0, 30)
    np.testing.assert_allclose(
        cascade.frequency_response(omega),
        first.frequency_response(omega) * second.frequency_response(omega),
        rtol=1e-10,
    )
    np.testing.assert_allclose(
        sorted_poles(cascade.poles()),
        sorted_poles(np.concatenate([first.poles(), second.poles()])),
    )


def test_feedback_poles_match_the_hand_assembled_closed_loop():
    plant, controller = random_model(4, 3), random_model(5, 2, feedthrough=0.3)
    A, B, C = plant.A, plant.B, plant.C
    Ac, Bc, Cc, Dc = controller.A, controller.B, controller.C, controller.D
    # u = Cc xc + Dc C x with a strictly proper plant.
    closed = np.block([[A + B @ Dc @ C, B @ Cc], [Bc @ C, Ac]])
    np.testing.assert_allclose(
        sorted_poles(feedback_loop_poles(plant, controller)),
        sorted_poles(np.linalg.eigvals(closed)),
        atol=1e-9,
    )


def test_feedback_poles_of_a_static_gain_are_those_of_a_minus_b_k_c():
    plant = random_model(6, 4)
    K = 0.8
    np.testing.assert_allclose(
        sorted_poles(feedback_loop_poles(plant, LinearModel.static_gain(-K, TS))),
        sorted_poles(np.linalg.eigvals(plant.A - K * plant.B @ plant.C)),
        atol=1e-9,
    )


@pytest.mark.parametrize("plant_feedthrough", [0.0, 0.5])
def test_feedback_poles_are_the_zeros_of_one_plus_the_loop_transfer(plant_feedthrough):
    # 1 + L = (den + num) / den with den = det(zI - A_L), so the zeros are the roots of den + num,
    # hidden modes included: an independent check of the sign convention.
    plant = random_model(7, 3, plant_feedthrough)
    controller = random_model(8, 2, feedthrough=-0.6)
    loop = loop_transfer(plant, controller)
    num, den = scipy.signal.ss2tf(loop.A, loop.B, loop.C, loop.D)
    np.testing.assert_allclose(
        sorted_poles(feedback_loop_poles(plant, controller)),
        sorted_poles(np.roots(den + num[0])),
        atol=1e-8,
    )


def test_lqg_closed_loop_poles_are_the_regulator_and_observer_poles():
    plant, controller, (regulator, observer) = lqg_loop()
    np.testing.assert_allclose(
        sorted_poles(feedback_loop_poles(plant, controller)),
        sorted_poles(np.concatenate([np.linalg.eigvals(regulator), np.linalg.eigvals(observer)])),
        atol=1e-9,
    )


@pytest.mark.parametrize("delay_samples", [0, 1, 3])
def test_a_delay_lowers_the_phase_margin_by_the_closed_form_lag(delay_samples):
    loop = loop_transfer(integrator(TS), LinearModel.static_gain(-5.0, TS))
    delayed = added_delay_samples_loop(loop, delay_samples)
    omega = np.geomspace(0.1, math.pi / TS, 25)
    np.testing.assert_allclose(
        delayed.frequency_response(omega),
        loop.frequency_response(omega) * np.exp(-1j * omega * delay_samples * TS),
        rtol=1e-10,
    )
    assert delayed.order == loop.order + delay_samples
    before, after = discrete_margins(loop), discrete_margins(delayed)
    assert after.gain_crossover_rad_s == pytest.approx(before.gain_crossover_rad_s, rel=1e-9)
    lag_deg = math.degrees(before.gain_crossover_rad_s * delay_samples * TS)
    assert after.phase_margin_deg == pytest.approx(before.phase_margin_deg - lag_deg, rel=1e-9)


@pytest.mark.parametrize("make_loop", ["integrator", "lqg"])
def test_the_delay_margin_separates_stable_and_unstable_whole_sample_delays(make_loop):
    if make_loop == "integrator":  # tolerates 7.67 samples
        plant, controller = integrator(TS), LinearModel.static_gain(-4.0, TS)
    else:
        plant, controller, _ = lqg_loop()
    margin_samples = discrete_margins(loop_transfer(plant, controller)).delay_margin_s / TS
    tolerated = math.floor(margin_samples)
    assert 0.05 < margin_samples - tolerated < 0.95  # not at the boundary, where rounding decides
    delayed = [added_delay_samples_loop(plant, d) for d in (tolerated, tolerated + 1)]
    assert stable(feedback_loop_poles(delayed[0], controller))
    assert not stable(feedback_loop_poles(delayed[1], controller))


@pytest.mark.parametrize("make_loop", ["integrator", "lqg"])
def test_gain_just_inside_the_gain_margin_is_stable_and_just_outside_is_not(make_loop):
    if make_loop == "integrator":
        plant, controller = integrator(TS), LinearModel.static_gain(-5.0, TS)
    else:
        plant, controller, _ = lqg_loop()
    margins = discrete_margins(loop_transfer(plant, controller))
    assert math.isfinite(margins.gain_margin) and margins.gain_margin > 1.0
    assert stable(feedback_loop_poles(plant, controller))
    assert stable(feedback_loop_poles(plant, scaled(controller, 0.999 * margins.gain_margin)))
    assert not stable(feedback_loop_poles(plant, scaled(controller, 1.001 * margins.gain_margin)))
    # At the phase crossover L is real and negative, -1 / gain_margin.
    at_crossover = loop_transfer(plant, controller).frequency_response(
        margins.phase_crossover_rad_s
    )
    assert at_crossover == pytest.approx(-1.0 / margins.gain_margin, abs=1e-9)


def test_a_negative_dc_gain_is_a_phase_crossing_at_zero_frequency():
    # L = c / (z - 0.5), c < 0: L(1) = 2c; a gain 1 / |2c| puts a closed-loop pole at z = 1.
    c = -0.1
    loop = LinearModel([[0.5]], [[1.0]], [[c]], [[0.0]], TS)
    margins = discrete_margins(loop)
    assert margins.phase_crossover_rad_s == 0.0
    assert margins.gain_margin == pytest.approx(0.5 / abs(c), rel=1e-12)
    assert margins.phase_margin_deg == math.inf  # |L| <= 0.2 everywhere


def test_no_crossings_give_infinite_margins_and_json_safe_values():
    # L = 0.1 z / (z - 0.5): |L| <= 0.2 and -90° < ∠L <= 0°, positive at both band edges.
    loop = LinearModel([[0.5]], [[1.0]], [[0.05]], [[0.1]], TS)
    margins = discrete_margins(loop)
    assert margins.as_dict() == {
        "gain_margin": "inf",
        "gain_margin_db": "inf",
        "phase_crossover_rad_s": None,
        "phase_margin_deg": "inf",
        "gain_crossover_rad_s": None,
        "delay_margin_s": "inf",
    }
    json.dumps(margins.as_dict(), allow_nan=False)


def test_as_dict_keeps_finite_margins():
    margins = Margins(2.0, 20 * math.log10(2.0), 30.0, 45.0, 5.0, math.radians(45.0) / 5.0)
    assert margins.as_dict()["phase_margin_deg"] == 45.0
    assert json.loads(json.dumps(margins.as_dict(), allow_nan=False))["gain_margin"] == 2.0


def test_bad_arguments_are_rejected_naming_the_argument():
    plant, other_rate = integrator(TS), integrator(0.01)
    with pytest.raises(ValueError, match="first and second must share one sample period"):
        series(plant, other_rate)
    with pytest.raises(ValueError, match="plant and controller must share one sample period"):
        feedback_loop_poles(plant, other_rate)
    with pytest.raises(ValueError, match=r"sign must be \+1 or -1"):
        loop_transfer(plant, plant, sign=2)
    with pytest.raises(ValueError, match="ill-posed algebraic loop"):
        feedback_loop_poles(LinearModel.static_gain(2.0, TS), LinearModel.static_gain(0.5, TS))
    for delay in (-1, 1.5, True):
        with pytest.raises(ValueError, match="delay_samples must be a non-negative integer"):
            added_delay_samples_loop(plant, delay)
    with pytest.raises(ValueError, match="n_frequencies must be an integer >= 16"):
        discrete_margins(plant, n_frequencies=8)
