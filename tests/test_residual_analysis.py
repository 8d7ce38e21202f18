"""Residual correlations of white, AR(1) and input-driven residuals against their known values."""

import numpy as np
import pytest

from maskless.analysis.identification.residual_analysis import residual_correlations


def test_white_residuals_independent_of_the_input_stay_in_the_band():
    rng = np.random.default_rng(0)
    c = residual_correlations(rng.normal(size=20000), rng.normal(size=20000))
    assert c.band == pytest.approx(2.5758 / np.sqrt(20000), rel=1e-4)
    outside = c.fraction_outside()
    # 99 % bands: about 1 % of lags outside by chance; allow a few.
    assert outside["autocorrelation"] <= 0.1 and outside["cross_correlation"] <= 0.1


def test_ar1_residuals_show_their_lag_one_correlation():
    rng = np.random.default_rng(1)
    white = rng.normal(size=50000)
    e = np.empty_like(white)
    e[0] = white[0]
    for k in range(1, e.size):
        e[k] = 0.6 * e[k - 1] + white[k]
    c = residual_correlations(e, rng.normal(size=e.size))
    # AR(1): r(τ)/r(0) = 0.6^τ.
    np.testing.assert_allclose(c.autocorrelation[1:4], [0.6, 0.36, 0.216], atol=0.02)


def test_residuals_driven_by_a_delayed_input_peak_at_that_lag():
    rng = np.random.default_rng(2)
    u = rng.normal(size=20000)
    e = np.roll(u, 3) + 0.1 * rng.normal(size=u.size)
    c = residual_correlations(e, u)
    assert c.cross_lags[np.argmax(np.abs(c.cross_correlation))] == 3
