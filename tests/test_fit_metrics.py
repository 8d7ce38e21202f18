import math

import numpy as np
import pytest

from maskless.analysis.fit_metrics import evaluate_fit, fit_percent


def test_fit_percent_of_a_hand_example():
    y = np.array([1.0, 2.0, 3.0, 4.0])
    y_hat = np.array([1.0, 2.0, 3.0, 3.0])
    # ||e|| = 1, ||y - mean|| = sqrt(1.25^2*2 + 0.25^2*2... ) = sqrt(5)
    assert fit_percent(y, y_hat) == pytest.approx(100 * (1 - 1 / math.sqrt(5)))
    assert fit_percent(y, y) == 100.0


def test_figures_match_matlabs_definitions():
    rng = np.random.default_rng(0)
    y = rng.normal(size=500)
    y_hat = y + 0.1 * rng.normal(size=500)
    m = evaluate_fit(y, y_hat, parameters=8)
    V, N, d = np.mean((y - y_hat) ** 2), 500, 8
    assert m.mse == pytest.approx(V)
    assert m.fpe == pytest.approx(V * (1 + d / N) / (1 - d / N))
    assert m.naic == pytest.approx(math.log(V) + 2 * d / N)
    assert m.aic == pytest.approx(N * math.log(V) + 2 * d + N * (math.log(2 * math.pi) + 1))
    assert m.bic == pytest.approx(
        N * math.log(V) + N * (math.log(2 * math.pi) + 1) + d * math.log(N)
    )


def test_fpe_of_matlabs_saved_report():
    # shared/paper-data/README.md: MSE 0.00060058 with N = 11782, d = 8 gives FPE 0.0006014.
    V, N, d = 0.00060058, 11782, 8
    assert V * (1 + d / N) / (1 - d / N) == pytest.approx(0.0006014, rel=1e-4)


def test_constant_output_has_no_fit():
    with pytest.raises(ValueError, match="constant"):
        fit_percent(np.ones(5), np.zeros(5))
