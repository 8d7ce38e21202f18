"""The local Kalman filter: Eq. 8-9 one step at a time, the steady state against scipy's DARE."""

import numpy as np
import pytest
import scipy.linalg
from system_harness import port_layout

from maskless.diagrams.scenario import load_scenario
from maskless.errors import ConfigError
from maskless.systems.sensing.local_kalman_filter import (
    LocalFilterConfig,
    make_local_kalman_filter,
    steady_state_covariances,
)

CAMERA_M = 1.0
PERIOD_S = 1 / 15
SIGMA_A2 = 2000e-6  # the paper's "sigma_a = 2000 mm^2", as a variance in m^2/s^4
SIGMA_R2 = 70e-6
START_M = 0.2
VALID_RANGE_M = (0.4, 4.0)
CONFIG = LocalFilterConfig(initial_position_std_m=0.01, initial_velocity_std_m_s=0.02)
DETECTION = load_scenario().fault_detection  # the shipped checks


@pytest.fixture(scope="module")
def kf():
    return make_local_kalman_filter(
        "kinect_v1_filter",
        camera_height_m=CAMERA_M,
        frame_period_s=PERIOD_S,
        acceleration_variance_m2_s4=SIGMA_A2,
        measurement_variance_m2=SIGMA_R2,
        initial_height_m=START_M,
        valid_range_m=VALID_RANGE_M,
        config=CONFIG,
        detection=DETECTION,
    )


def eq_8_9(x, P, z, dt, sigma_a2, sigma_r2):
    """Eq. 4, 6, 8 and 9 written out."""
    F = np.array([[1, dt], [0, 1]])
    W = np.array([[dt**2 / 2], [dt]])
    Q = W @ W.T * sigma_a2
    H = np.array([[1.0, 0.0]])
    x_prior = F @ x
    P_prior = F @ P @ F.T + Q
    if z is None:
        return x_prior, P_prior
    K = P_prior @ H.T @ np.linalg.inv(H @ P_prior @ H.T + sigma_r2)
    x_post = x_prior + (K @ (np.array([z]) - H @ x_prior))
    P_post = (np.eye(2) - K @ H) @ P_prior
    return x_post, P_post


def context_at(kf, x, P, last_tick_s, now_s, distance, valid):
    """A context whose filter holds (x, P) from ``last_tick_s``, at time ``now_s``."""
    context = kf.CreateDefaultContext()
    P0 = np.diag([CONFIG.initial_position_std_m**2, CONFIG.initial_velocity_std_m_s**2])
    offsets = np.concatenate(
        [x - [START_M, 0.0], [P[0, 0] - P0[0, 0], P[0, 1], P[1, 1] - P0[1, 1]]]
    )
    # The checks' memory: a usable frame at the last tick, none rejected or repeated since.
    checks = [last_tick_s, 0.0, 0.0, 0.0]
    context.SetDiscreteState(np.concatenate([offsets, [last_tick_s], checks]))
    context.SetTime(now_s)
    kf.GetInputPort("distance_m").FixValue(context, [distance])
    kf.GetInputPort("valid").FixValue(context, [valid])
    return context


def step(kf, context):
    """The state after the tick at the context's time, as (x, P)."""
    s = kf.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    P0 = np.diag([CONFIG.initial_position_std_m**2, CONFIG.initial_velocity_std_m_s**2])
    x = s[:2] + [START_M, 0.0]
    P = np.array([[s[2], s[3]], [s[3], s[4]]]) + P0
    return x, P


def test_ports(kf):
    assert kf.get_name() == "kinect_v1_filter"
    assert port_layout(kf) == (
        {"distance_m": 1, "valid": 1},
        {"estimated_state": 2, "covariance": 4, "health": 3},
    )


def test_default_context_starts_at_the_configured_estimate(kf):
    context = kf.CreateDefaultContext()
    np.testing.assert_allclose(kf.GetOutputPort("estimated_state").Eval(context), [START_M, 0.0])
    np.testing.assert_allclose(
        kf.GetOutputPort("covariance").Eval(context), [1e-4, 0.0, 0.0, 4e-4], rtol=1e-12
    )


@pytest.mark.parametrize("distance", [0.79, 0.805, 0.77])
def test_one_step_matches_eq_8_9(kf, distance):
    x = np.array([0.21, 0.003])
    P = np.array([[2e-5, 1e-5], [1e-5, 3e-4]])
    context = context_at(
        kf, x, P, last_tick_s=1.0, now_s=1.0 + PERIOD_S, distance=distance, valid=1.0
    )
    x_new, P_new = step(kf, context)
    x_ref, P_ref = eq_8_9(x, P, CAMERA_M - distance, PERIOD_S, SIGMA_A2, SIGMA_R2)
    np.testing.assert_allclose(x_new, x_ref, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(P_new, P_ref, rtol=1e-10, atol=1e-18)


@pytest.mark.parametrize(
    "distance, valid",
    [(0.0, 1.0), (np.nan, 1.0), (np.inf, 1.0), (-0.3, 1.0), (0.79, 0.0), (7.0, 1.0), (1e-6, 1.0)],
    ids=["zero", "nan", "inf", "negative", "flagged_invalid", "beyond_range", "nearer_than_range"],
)
def test_unusable_frames_only_predict(kf, distance, valid):
    x = np.array([0.21, 0.003])
    P = np.array([[2e-5, 1e-5], [1e-5, 3e-4]])
    context = context_at(kf, x, P, 1.0, 1.0 + PERIOD_S, distance, valid)
    x_new, P_new = step(kf, context)
    x_ref, P_ref = eq_8_9(x, P, None, PERIOD_S, SIGMA_A2, SIGMA_R2)
    assert np.all(np.isfinite(x_new)) and np.all(np.isfinite(P_new))
    np.testing.assert_allclose(x_new, x_ref, rtol=1e-12)
    np.testing.assert_allclose(P_new, P_ref, rtol=1e-10)


def test_output_is_predicted_to_the_current_time(kf):
    x = np.array([0.21, 0.003])
    P = np.array([[2e-5, 1e-5], [1e-5, 3e-4]])
    context = context_at(kf, x, P, last_tick_s=1.0, now_s=1.03, distance=0.79, valid=1.0)
    x_ref, P_ref = eq_8_9(x, P, None, 0.03, SIGMA_A2, SIGMA_R2)
    np.testing.assert_allclose(kf.GetOutputPort("estimated_state").Eval(context), x_ref)
    np.testing.assert_allclose(kf.GetOutputPort("covariance").Eval(context), P_ref.ravel())


def scipy_steady_state(dt, sigma_a2, sigma_r2):
    F = np.array([[1, dt], [0, 1]])
    W = np.array([[dt**2 / 2], [dt]])
    H = np.array([[1.0, 0.0]])
    prior = scipy.linalg.solve_discrete_are(F.T, H.T, W @ W.T * sigma_a2, np.array([[sigma_r2]]))
    posterior = prior - prior @ H.T @ H @ prior / (H @ prior @ H.T + sigma_r2)
    return F, H, prior, posterior


def test_steady_state_covariance_matches_scipy_dare():
    _, _, prior_ref, posterior_ref = scipy_steady_state(PERIOD_S, SIGMA_A2, SIGMA_R2)
    prior, posterior = steady_state_covariances(PERIOD_S, SIGMA_A2, SIGMA_R2)
    np.testing.assert_allclose(prior, prior_ref, rtol=1e-9)
    np.testing.assert_allclose(posterior, posterior_ref, rtol=1e-9)


def test_running_filter_converges_to_the_dare_solution(kf):
    _, _, _, posterior_ref = scipy_steady_state(PERIOD_S, SIGMA_A2, SIGMA_R2)
    context = kf.CreateDefaultContext()
    kf.GetInputPort("distance_m").FixValue(context, [0.8])
    kf.GetInputPort("valid").FixValue(context, [1.0])
    for k in range(1, 400):
        context.SetTime(k * PERIOD_S)
        context.SetDiscreteState(
            kf.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
        )
    _, P = step(kf, context)
    # One more tick from the converged state: P is the DARE's posterior.
    np.testing.assert_allclose(P, posterior_ref, rtol=1e-6)


def test_reading_of_sigma_a_matches_the_reported_noise_reduction():
    # The paper reports the Xbox filter cut the measurement variance by 80.81 % (Sec. III-B), at
    # 15 Hz with sigma_r1^2 = 70 mm^2. The steady-state filter passes white noise to its estimate
    # with variance gain from the Lyapunov equation of (I - K H) F driven by K.
    def variance_reduction_percent(sigma_a2_mm2):
        F, H, prior, _ = scipy_steady_state(PERIOD_S, sigma_a2_mm2, 70.0)
        K = prior @ H.T / (H @ prior @ H.T + 70.0)
        closed = (np.eye(2) - K @ H) @ F
        gain = scipy.linalg.solve_discrete_lyapunov(closed, K @ K.T)[0, 0]
        return 100 * (1 - gain)

    as_variance = variance_reduction_percent(2000.0)  # sigma_a^2 = 2000 (mm/s^2)^2
    as_std = variance_reduction_percent(2000.0**2)  # sigma_a = 2000 mm/s^2
    assert abs(as_variance - 80.81) < 5
    assert abs(as_std - 80.81) > 40


def test_bad_parameters_are_refused():
    with pytest.raises(ConfigError, match="measurement_variance_m2"):
        make_local_kalman_filter(
            "f",
            camera_height_m=1.0,
            frame_period_s=PERIOD_S,
            acceleration_variance_m2_s4=1.0,
            measurement_variance_m2=0.0,
            initial_height_m=0.2,
            valid_range_m=VALID_RANGE_M,
            config=CONFIG,
            detection=DETECTION,
        )
