"""N4SID: poles and static gains of systems simulated by scipy, and its horizon rule."""

import numpy as np
import pytest
import scipy.linalg
import scipy.signal
from identification_records import (
    TRUE_SYSTEMS,
    largest_pole_error,
    scipy_dc_gain,
    simulate_record,
)

from maskless.analysis.identification.subspace import (
    LONGEST_PAST_HORIZON,
    estimate_n4sid,
    minimum_samples,
)

# (order, noise, samples, largest pole error allowed) on the records test_prediction_error.py fits
# by prediction error. Subspace estimates spread more than prediction-error ones on the same data
# (measured 0.007-0.044 over seeds 0-2 at 20,000 samples, order 4); the benchmark shows them
# converge.
CASES = [
    (2, "white", 5000, 0.01),
    (2, "coloured", 5000, 0.01),
    (4, "white", 20000, 0.06),
    (4, "coloured", 20000, 0.06),
]


@pytest.mark.parametrize("order, noise, samples, tolerance", CASES)
def test_n4sid_recovers_poles_and_static_gain(order, noise, samples, tolerance):
    u, y, a, b = simulate_record(order, noise, samples)
    model = estimate_n4sid(u, y, order, 1.0)[0].linear_model()
    assert largest_pole_error(model.poles(), TRUE_SYSTEMS[order]["poles"]) < tolerance
    true_gain = b.sum() / a.sum()  # B(1) / A(1)
    assert scipy_dc_gain(model) == pytest.approx(true_gain, rel=0.03)
    assert model.dc_gain() == pytest.approx(scipy_dc_gain(model), rel=1e-9)


def test_n4sid_recovers_a_resonant_pair_simulated_by_dlsim():
    # x(k+1) = A x + B u, y = C x + v: poles 0.8 ± 0.3j, white u and white measurement noise v
    # (std 0.5 against an output std of about 3), so the noise is not the model's innovations.
    A = np.array([[1.6, -0.73], [1.0, 0.0]])
    B = np.array([[1.0], [0.0]])
    C = np.array([[0.5, 0.3]])
    true_poles = np.linalg.eigvals(A)
    np.testing.assert_allclose(np.sort_complex(true_poles), [0.8 - 0.3j, 0.8 + 0.3j])
    rng = np.random.default_rng(0)
    u = rng.standard_normal(5000)
    _, clean, _ = scipy.signal.dlsim((A, B, C, np.zeros((1, 1)), 0.1), u)
    y = clean[:, 0] + 0.5 * rng.standard_normal(u.size)
    fit = estimate_n4sid(u, y, 2, 0.1)
    model, singular_values = fit.model.linear_model(), fit.singular_values
    # Measured 1e-5 to 0.003 over seeds 0-9.
    assert largest_pole_error(model.poles(), true_poles) < 0.01
    true_gain = (C @ np.linalg.solve(np.eye(2) - A, B))[0, 0]  # C (I - A)^-1 B
    assert model.dc_gain() == pytest.approx(true_gain, rel=0.02)
    # Two states stand out: the third singular value is under a tenth of the second.
    assert singular_values[2] < 0.1 * singular_values[1]
    assert model.sample_period_s == 0.1


def arx_bic_past_horizon(u, y, order, longest, future):
    """The past horizon BIC picks, by ordinary least squares on each ARX(p, p) regression.

    The equations are the subspace fit's: y(t) for t = longest .. N - future, regressed on the
    future inputs u(t) .. u(t + f - 1) and the newest p past inputs and outputs.
    """
    times = np.arange(longest, y.size - future + 1)
    future_inputs = [u[times + j] for j in range(future)]
    criteria = {}
    for p in range(order + 1, longest + 1):
        past = [s[times - lag] for lag in range(1, p + 1) for s in (u, y)]
        regressors = np.column_stack(future_inputs + past)
        solution, *_ = scipy.linalg.lstsq(regressors, y[times], lapack_driver="gelsy")
        residual = np.sum((y[times] - regressors @ solution) ** 2)
        m = times.size
        criteria[p] = m * np.log(residual / m) + 2 * p * np.log(m)
    return min(criteria, key=criteria.get)


@pytest.mark.parametrize("noise_zeros", [[0.2, -0.1], [0.95, 0.9]])
def test_past_horizon_is_the_arx_order_bic_picks(noise_zeros):
    # Reference: each ARX regression solved by numpy's least squares on its own; the estimator
    # reads them all from one Cholesky factor of a Gram matrix.
    rng = np.random.default_rng(5)
    u = rng.standard_normal(1500)
    a = np.poly([0.9, 0.7])
    y = scipy.signal.lfilter([0, 0.5, 0.3], a, u) + scipy.signal.lfilter(
        np.poly(noise_zeros), a, 0.3 * rng.standard_normal(u.size)
    )
    fit = estimate_n4sid(u, y, 2, 1.0)
    assert fit.future_horizon == 6  # 2n + 2
    assert fit.past_horizon == arx_bic_past_horizon(u, y, 2, LONGEST_PAST_HORIZON, 6)


def test_a_slow_noise_model_gets_a_longer_past_horizon():
    # A predictor with roots at 0.95 and 0.9 forgets slowly: the past must reach further back
    # than for a white-noise ARX system, whose predictor needs only n past samples.
    u, y, _, _ = simulate_record(2, "white", 5000)
    short = estimate_n4sid(u, y, 2, 1.0).past_horizon
    rng = np.random.default_rng(0)
    a = np.poly([0.9, 0.7])
    slow = scipy.signal.lfilter([0, 0.5, 0.3], a, u) + scipy.signal.lfilter(
        np.poly([0.95, 0.9]), a, 0.3 * rng.standard_normal(u.size)
    )
    assert estimate_n4sid(u, slow, 2, 1.0).past_horizon > short


def test_given_horizons_are_used():
    # The projected future outputs have ``future_horizon`` rows: one singular value each.
    u, y, _, _ = simulate_record(2, "white", 2000)
    fit = estimate_n4sid(u, y, 2, 1.0, past_horizon=12, future_horizon=8)
    assert (fit.past_horizon, fit.future_horizon, fit.singular_values.size) == (12, 8, 8)


@pytest.mark.parametrize(
    "order, past_horizon, samples, message",
    [
        (0, None, 2000, "order = 0: expected a positive integer"),
        (3, 3, 2000, "need 1 <= order < each horizon"),
        (2, None, 97, "97 samples are too few for an order-2 subspace fit: need at least 98"),
        (2, 30, 300, "300 samples are too few for past horizon 30 and future horizon 6"),
    ],
)
def test_bad_orders_horizons_and_records_are_refused(order, past_horizon, samples, message):
    u, y, _, _ = simulate_record(2, "white", samples)
    with pytest.raises(ValueError, match=message):
        estimate_n4sid(u, y, order, 1.0, past_horizon=past_horizon)


def test_an_unstable_fit_gives_a_model_not_a_traceback():
    # An unstable system (pole 1.02) on 20,000 samples: B and x(0) are fitted on the samples
    # before its response grows a millionfold, so nothing overflows.
    rng = np.random.default_rng(2)
    u = rng.standard_normal(20_000)
    y = np.zeros(u.size)
    y[:600] = scipy.signal.lfilter([0, 1.0], [1, -1.02], u[:600])
    y[600:] = rng.standard_normal(u.size - 600)
    model = estimate_n4sid(u, y, 1, 1.0).model
    assert np.all(np.isfinite(model.b)) and np.all(np.isfinite(model.initial_state))
    assert all(abs(p) < 1 for p in model.predictor_poles())


def test_signals_of_different_lengths_are_refused():
    u, y, _, _ = simulate_record(2, "white", 2000)
    with pytest.raises(ValueError, match="one length"):
        estimate_n4sid(u[:-1], y, 2, 1.0)


@pytest.mark.parametrize("order", [1, 2, 4])
def test_minimum_samples_is_the_shortest_record_accepted(order):
    u, y, _, _ = simulate_record(2, "white", minimum_samples(order))
    assert estimate_n4sid(u, y, order, 1.0).past_horizon == order + 1
    with pytest.raises(ValueError, match=f"need at least {minimum_samples(order)}"):
        estimate_n4sid(u[1:], y[1:], order, 1.0)
