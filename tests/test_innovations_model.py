"""The innovations model: prediction and simulation against the state-space recursion and scipy."""

import numpy as np
import pytest
import scipy.signal

from maskless.analysis.identification.innovations_model import (
    InnovationsModel,
    samples_before_growth,
)

MODEL = InnovationsModel(
    a=np.array([-1.5, 0.56]),
    b=np.array([0.4, -0.1]),
    k=np.array([0.3, -0.2]),
    sample_period_s=0.048,
    initial_state=np.array([0.5, -0.2]),
)


def recursion(model, u, y, x0, one_step):
    """Eq. 25 run sample by sample: x(k+1) = A x + B u + K (y - C x) (one step) or A x + B u."""
    m = model.linear_model()
    x, out = np.array(x0, float), []
    for uk, yk in zip(u, y, strict=True):
        yhat = (m.C @ x)[0]
        out.append(yhat)
        x = m.A @ x + m.B[:, 0] * uk + (m.K[:, 0] * (yk - yhat) if one_step else 0)
    return np.array(out)


def test_one_step_prediction_matches_the_state_space_recursion():
    rng = np.random.default_rng(1)
    u, y = rng.normal(size=300), rng.normal(size=300)
    np.testing.assert_allclose(
        MODEL.predict(u, y), recursion(MODEL, u, y, MODEL.initial_state, True), atol=1e-12
    )


def test_simulation_matches_the_recursion_and_scipy():
    u = np.random.default_rng(2).normal(size=300)
    simulated = MODEL.simulate(u, np.zeros(2))
    np.testing.assert_allclose(simulated, recursion(MODEL, u, u, np.zeros(2), False), atol=1e-12)
    m = MODEL.linear_model()
    _, reference, _ = scipy.signal.dlsim((m.A, m.B, m.C, m.D, 1.0), u)
    np.testing.assert_allclose(simulated, reference[:, 0], atol=1e-12)


def test_the_linear_model_has_the_polynomials_poles_and_gain():
    # Observer canonical form: the poles are the roots of A(z), the DC gain is B(1) / A(1).
    m = MODEL.linear_model(innovations_variance=0.01)
    np.testing.assert_allclose(
        np.sort_complex(m.poles()), np.sort_complex(np.roots([1.0, *MODEL.a]))
    )
    assert m.dc_gain() == pytest.approx(MODEL.b.sum() / (1.0 + MODEL.a.sum()), rel=1e-12)
    np.testing.assert_array_equal(m.K[:, 0], MODEL.k)
    assert (m.D[0, 0], m.sample_period_s, m.innovations_variance) == (0.0, 0.048, 0.01)
    assert m.is_stable()


@pytest.mark.parametrize("horizon", ["one_step", "simulation"])
def test_initial_state_is_recovered_from_a_record(horizon):
    rng = np.random.default_rng(3)
    u = rng.normal(size=400)
    x0 = np.array([1.5, -0.7])
    y = MODEL.simulate(u, x0)  # noise-free: both horizons must find x0 exactly
    np.testing.assert_allclose(MODEL.initial_state_for(u, y, horizon), x0, atol=1e-9)


@pytest.mark.parametrize("steps", [1, 3, 10])
def test_k_step_prediction_matches_running_the_predictor_then_the_model(steps):
    rng = np.random.default_rng(4)
    u, y = rng.normal(size=200), rng.normal(size=200)
    model = InnovationsModel(
        a=MODEL.a, b=MODEL.b, k=MODEL.k, sample_period_s=1.0, initial_state=np.zeros(2)
    )
    m = model.linear_model()
    # Reference: the one-step predictor's state x(t-k+1 | t-k), then k-1 steps of the model with
    # the known inputs and no innovations.
    states = [np.zeros(2)]
    for uk, yk in zip(u, y, strict=True):
        x = states[-1]
        states.append(m.A @ x + m.B[:, 0] * uk + m.K[:, 0] * (yk - x[0]))
    reference = np.zeros(200)
    for t in range(200):
        origin = t - steps + 1  # x(origin | origin - 1) uses data up to t - k
        if origin < 0:
            continue
        x = states[origin]
        for j in range(origin, t):
            x = m.A @ x + m.B[:, 0] * u[j]
        reference[t] = x[0]
    predicted = model.predict_k_steps(u, y, steps)
    np.testing.assert_allclose(predicted[steps:], reference[steps:], atol=1e-10)
    if steps == 1:
        np.testing.assert_allclose(predicted, model.predict(u, y), atol=1e-12)


@pytest.mark.parametrize(
    "largest, expected", [(0.9, 65_000), (1.0, 65_000), (1.05, 283), (2.0, 19)]
)
def test_samples_before_growth_is_where_the_largest_pole_grows_a_millionfold(largest, expected):
    # Closed form: the largest m with largest^m <= 1e6, i.e. floor(ln 1e6 / ln largest).
    assert samples_before_growth(np.array([0.5, -largest]), 65_000) == expected
    if largest > 1:
        assert largest**expected <= 1e6 < largest ** (expected + 1)


@pytest.mark.parametrize("horizon", ["one_step", "simulation"])
def test_initial_state_of_an_unstable_model_on_a_long_record(horizon):
    # Before issue 14 the least squares took the free response over all 65,000 samples, which
    # overflowed (LinAlgError, "SVD did not converge"). Roots at 1.05 and 0.5: A(z)'s for
    # "simulation", C(z)'s (the predictor's) for "one_step". The record is the model's noise-free
    # output (so the one-step prediction is exact too) for 300 samples, past the 283 used, then
    # noise.
    unstable, stable = np.real(np.poly([1.05, 0.5]))[1:], np.real(np.poly([0.4, 0.2]))[1:]
    a, c = (unstable, stable) if horizon == "simulation" else (stable, unstable)
    model = InnovationsModel(
        a=a, b=np.array([0.4, -0.1]), k=c - a, sample_period_s=1.0, initial_state=np.zeros(2)
    )
    rng = np.random.default_rng(6)
    u, y = rng.normal(size=65_000), rng.normal(size=65_000)
    x0 = np.array([1.5, -0.7])
    y[:300] = model.simulate(u[:300], x0)
    np.testing.assert_allclose(model.initial_state_for(u, y, horizon), x0, atol=1e-6)
