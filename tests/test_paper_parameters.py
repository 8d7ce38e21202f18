"""The paper's values as printed (Eq. 26, Eq. 30, Sec. III-B) and their SI conversions."""

import numpy as np
import pytest

from maskless.systems.paper_parameters import (
    load_paper_parameters,
    paper_filter_variances_si,
    paper_identified_model,
    paper_lqg_weights,
)


@pytest.fixture(scope="module")
def paper():
    return load_paper_parameters()


def test_values_as_printed_in_the_paper(paper):
    # Eq. 26, Eq. 30 and Sec. III-B, copied from the paper's text.
    assert paper.A == [[0.0, 1.0], [-0.9883, 1.988]]
    assert paper.B_mm_per_ma == [-3.03e-07, -4.254e-07]
    assert paper.K == [0.9253, 0.9604]
    assert (paper.lqr_Q_diagonal, paper.lqr_R) == (1.0566, 0.058006)
    assert (paper.estimator_Qe_diagonal, paper.estimator_Re) == (0.4511, 0.01)
    assert paper.acceleration_variance_mm2 == 2000.0
    assert paper.measurement_variance_kinect_v1_mm2 == 70.0
    assert paper.measurement_variance_kinect_v2_mm2 == 60.0
    assert paper.sample_period_s == 0.048


def test_model_in_si(paper):
    model = paper_identified_model(paper)
    np.testing.assert_array_equal(model.A, [[0.0, 1.0], [-0.9883, 1.988]])
    # mm/mA and m/A are the same ratio: 1 mm / 1 mA = 1e-3 m / 1e-3 A.
    np.testing.assert_allclose(model.B.ravel(), [-3.03e-07, -4.254e-07], rtol=1e-12)
    assert model.operating_output == pytest.approx(0.692357479)
    assert model.operating_input == pytest.approx(0.08132508)
    assert (model.input_unit, model.output_unit) == ("A", "m")


def test_dc_gain_matches_closed_form(paper):
    # C (I - A)^-1 B for A = [[0, 1], [a21, a22]], C = [1 0]: (b1 (1 - a22) + b2) / det(I - A)
    model = paper_identified_model(paper)
    (a21, a22), (b1, b2) = paper.A[1], paper.B_mm_per_ma
    det = (1 - a22) - (-1) * (-a21)
    assert model.dc_gain() == pytest.approx((b1 * (1 - a22) + b2) / det, rel=1e-9)


def test_lqg_weights_in_si_preserve_the_cost(paper):
    # J = x'Qx + R u^2 with x in mm and u in mA equals the SI cost with Q*1000^2 and R*1000^2.
    weights = paper_lqg_weights(paper)
    x_mm, u_ma = np.array([3.0, -2.0]), 40.0
    cost_printed = x_mm @ (np.eye(2) * paper.lqr_Q_diagonal) @ x_mm + paper.lqr_R * u_ma**2
    x_m, u_a = x_mm / 1000, u_ma / 1000
    cost_si = x_m @ weights.Q @ x_m + weights.R[0, 0] * u_a**2
    assert cost_si == pytest.approx(cost_printed, rel=1e-12)
    np.testing.assert_allclose(weights.W, np.eye(2) * 0.4511e-6)
    np.testing.assert_allclose(weights.V, [[0.01e-6]])


def test_filter_variances_in_si(paper):
    variances = paper_filter_variances_si(paper)
    assert variances["acceleration_variance_m2_s4"] == pytest.approx(2000e-6)
    assert variances["kinect_v1"] == pytest.approx(70e-6)
    assert variances["kinect_v2"] == pytest.approx(60e-6)
