"""N4SID: poles and static gains of systems simulated by scipy, and its documented horizon rule."""

import numpy as np
import pytest
import scipy.signal
from identification_records import (
    TRUE_SYSTEMS,
    largest_pole_error,
    scipy_dc_gain,
    simulate_record,
)

from maskless.analysis.identification.subspace import default_horizon, estimate_n4sid

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
    estimated, singular_values = estimate_n4sid(u, y, 2, 0.1)
    model = estimated.linear_model()
    # Measured 1e-5 to 0.003 over seeds 0-9.
    assert largest_pole_error(model.poles(), true_poles) < 0.01
    true_gain = (C @ np.linalg.solve(np.eye(2) - A, B))[0, 0]  # C (I - A)^-1 B
    assert model.dc_gain() == pytest.approx(true_gain, rel=0.02)
    # Two states stand out: the third singular value is under a tenth of the second.
    assert singular_values[2] < 0.1 * singular_values[1]
    assert model.sample_period_s == 0.1


@pytest.mark.parametrize(
    "order, horizon", [(1, 10), (2, 10), (3, 10), (4, 10), (5, 12), (6, 14), (10, 22)]
)
def test_default_horizon_is_the_documented_max_of_2n_plus_2_and_10(order, horizon):
    assert default_horizon(order) == horizon


def test_n4sid_uses_the_default_horizon_unless_given_one():
    # The projected future outputs have ``horizon`` rows: one singular value each.
    u, y, _, _ = simulate_record(2, "white", 2000)
    assert estimate_n4sid(u, y, 2, 1.0)[1].size == 10
    assert estimate_n4sid(u, y, 2, 1.0, horizon=12)[1].size == 12


@pytest.mark.parametrize(
    "order, horizon, samples, message",
    [
        (0, None, 2000, "need 1 <= order < horizon"),
        (3, 3, 2000, "need 1 <= order < horizon"),
        (2, None, 100, "100 samples are too few for horizon 10"),
    ],
)
def test_bad_orders_horizons_and_records_are_refused(order, horizon, samples, message):
    u, y, _, _ = simulate_record(2, "white", samples)
    with pytest.raises(ValueError, match=message):
        estimate_n4sid(u, y, order, 1.0, horizon=horizon)


def test_signals_of_different_lengths_are_refused():
    u, y, _, _ = simulate_record(2, "white", 2000)
    with pytest.raises(ValueError, match="one length"):
        estimate_n4sid(u[:-1], y, 2, 1.0)
