"""Residual analysis: is what the model leaves behind white, and independent of the input?

As MATLAB's ``resid``: the normalised autocorrelation of the residuals at lags 1..M with the 99 %
band ±2.576/√N of white residuals, and their cross-correlation with the input at lags -M..M with
the 99 % band of residuals independent of the input, ±2.576 √(1 + 2 Σ_{k=1..M} r_e(k) r_u(k)) / √N
(r_e, r_u the normalised autocorrelations; the sum widens the band for coloured signals).
"""

from dataclasses import dataclass

import numpy as np

# Two-sided 99 % quantile of the standard normal distribution.
_Z_99 = 2.5758293035489004


@dataclass(frozen=True)
class ResidualCorrelations:
    """Normalised correlations of a model's residuals.

    Attributes:
        lags: 0..M for the autocorrelation.
        autocorrelation: r_ee(τ) / r_ee(0) at ``lags``.
        cross_lags: -M..M for the cross-correlation.
        cross_correlation: r_ue(τ) / √(r_uu(0) r_ee(0)) at ``cross_lags`` (τ > 0: input leads).
        band: the autocorrelation's 99 % band half-width, 2.576/√N.
        cross_band: the cross-correlation's 99 % band half-width.
    """

    lags: np.ndarray
    autocorrelation: np.ndarray
    cross_lags: np.ndarray
    cross_correlation: np.ndarray
    band: float
    cross_band: float

    def fraction_outside(self) -> dict[str, float]:
        """Share of lags (excluding lag 0 of the autocorrelation) outside the band."""
        return {
            "autocorrelation": float(np.mean(np.abs(self.autocorrelation[1:]) > self.band)),
            "cross_correlation": float(np.mean(np.abs(self.cross_correlation) > self.cross_band)),
        }


def residual_correlations(residuals: np.ndarray, u: np.ndarray, max_lag: int = 25):
    """The correlations of ``residuals`` with themselves and with ``u`` up to ``max_lag``."""
    e = np.asarray(residuals, float) - np.mean(residuals)
    v = np.asarray(u, float) - np.mean(u)
    n = e.size
    if v.size != n or n <= max_lag:
        raise ValueError(
            f"residual_correlations: need equal lengths longer than max_lag={max_lag}, got "
            f"{n} residuals and {v.size} inputs"
        )
    lags = np.arange(max_lag + 1)
    auto = np.array([e[: n - lag] @ e[lag:] for lag in lags]) / n
    cross_lags = np.arange(-max_lag, max_lag + 1)
    # r_ue(τ) = (1/N) Σ u(k) e(k+τ): positive τ means the input comes first.
    cross = (
        np.array(
            [v[: n - lag] @ e[lag:] if lag >= 0 else v[-lag:] @ e[: n + lag] for lag in cross_lags]
        )
        / n
    )
    input_auto = np.array([v[: n - lag] @ v[lag:] for lag in lags]) / n
    if not v.any() or auto[0] == 0:
        raise ValueError("residual_correlations: the input or the residuals are constant")
    normalised_auto = auto / auto[0]
    normalised_input = input_auto / input_auto[0]
    widening = 1 + 2 * float(normalised_auto[1:] @ normalised_input[1:])
    return ResidualCorrelations(
        lags=lags,
        autocorrelation=normalised_auto,
        cross_lags=cross_lags,
        cross_correlation=cross / np.sqrt(auto[0] * input_auto[0]),
        band=_Z_99 / np.sqrt(n),
        cross_band=_Z_99 * np.sqrt(max(widening, 0.0)) / np.sqrt(n),
    )
