"""Residual analysis: is what the model leaves behind white, and independent of the input?

As MATLAB's ``resid``: the normalised autocorrelation of the residuals at lags 1..M and their
cross-correlation with the input at lags -M..M, each with a 99 % confidence band ±2.576/√N (the
band for white residuals independent of the input).
"""

from dataclasses import dataclass
from pathlib import Path

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
        band: the 99 % band half-width, 2.576/√N.
    """

    lags: np.ndarray
    autocorrelation: np.ndarray
    cross_lags: np.ndarray
    cross_correlation: np.ndarray
    band: float

    def fraction_outside(self) -> dict[str, float]:
        """Share of lags (excluding lag 0 of the autocorrelation) outside the band."""
        return {
            "autocorrelation": float(np.mean(np.abs(self.autocorrelation[1:]) > self.band)),
            "cross_correlation": float(np.mean(np.abs(self.cross_correlation) > self.band)),
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
    scale = np.sqrt(auto[0] * (v @ v / n)) if v.any() else 1.0
    return ResidualCorrelations(
        lags=lags,
        autocorrelation=auto / auto[0],
        cross_lags=cross_lags,
        cross_correlation=cross / scale,
        band=_Z_99 / np.sqrt(n),
    )


def plot_residual_correlations(path: str | Path, correlations: ResidualCorrelations, title: str):
    """Two panels, each with its 99 % band: the residuals' autocorrelation and their
    cross-correlation with the input."""
    from matplotlib.figure import Figure  # a bare Figure: no GUI backend, no pyplot

    figure = Figure(figsize=(9, 6), layout="constrained")
    auto, cross = figure.subplots(2, 1)
    band = correlations.band
    auto.stem(correlations.lags, correlations.autocorrelation, basefmt=" ")
    auto.axhspan(-band, band, color="tab:blue", alpha=0.15, label="99 % band")
    auto.set_title(f"{title}: autocorrelation of residuals")
    auto.set_xlabel("lag (samples)")
    auto.legend(loc="upper right")
    cross.stem(correlations.cross_lags, correlations.cross_correlation, basefmt=" ")
    cross.axhspan(-band, band, color="tab:blue", alpha=0.15)
    cross.set_title("cross-correlation of input and residuals")
    cross.set_xlabel("lag (samples; > 0: input leads)")
    figure.savefig(path, dpi=100)
    return Path(path)
