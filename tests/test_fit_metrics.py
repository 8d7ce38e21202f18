"""Fit figures (fit %, MSE, FPE, AIC, BIC) against hand examples and MATLAB's saved report."""

import math

import numpy as np
import pytest

from maskless.analysis.identification.fit_metrics import evaluate_fit, fit_percent


def test_fit_percent_of_a_hand_example():
    y = np.array([1.0, 2.0, 3.0, 4.0])
    y_hat = np.array([1.0, 2.0, 3.0, 3.0])
    # ||y - y_hat|| = 1; ||y - mean(y)|| = sqrt(1.5^2 + 0.5^2 + 0.5^2 + 1.5^2) = sqrt(5).
    assert fit_percent(y, y_hat) == pytest.approx(100 * (1 - 1 / math.sqrt(5)))
    assert fit_percent(y, y) == 100.0


def test_figures_of_a_hand_example():
    # Residuals of ±0.5 on N = 4 samples with d = 1: V = 0.25, and by hand (calculator)
    # FPE = 0.25 * 1.25 / 0.75, nAIC = ln 0.25 + 0.5, AIC = 4 ln 0.25 + 2 + 4 (ln 2π + 1),
    # BIC = 4 ln 0.25 + 4 (ln 2π + 1) + ln 4.
    y = np.array([1.0, 2.0, 3.0, 5.0])
    m = evaluate_fit(y, y + np.array([0.5, -0.5, 0.5, -0.5]), parameters=1)
    assert m.mse == pytest.approx(0.25)
    assert m.fpe == pytest.approx(0.4166666667)
    assert m.naic == pytest.approx(-0.8862943611)
    assert m.aic == pytest.approx(7.8063308212)
    assert m.bic == pytest.approx(7.1926251823)


def test_fpe_of_matlabs_saved_report():
    # shared/paper-data/README.md: MSE 0.00060058 with N = 11782, d = 8 gives FPE 0.0006014.
    n = 11782
    y = np.sin(np.arange(n))
    residual = np.sqrt(0.00060058) * np.where(np.arange(n) % 2, 1.0, -1.0)
    m = evaluate_fit(y, y + residual, parameters=8)
    assert m.mse == pytest.approx(0.00060058)
    assert m.fpe == pytest.approx(0.0006014, rel=1e-4)


def test_constant_output_has_no_fit():
    with pytest.raises(ValueError, match="constant"):
        fit_percent(np.ones(5), np.zeros(5))
