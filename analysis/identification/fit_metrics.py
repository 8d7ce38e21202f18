"""Model-quality figures exactly as MATLAB's System Identification Toolbox defines them.

For one output with N samples, residuals e = y - ŷ and d estimated parameters (initial states
included when estimated): fit % = 100 (1 - ‖e‖ / ‖y - mean(y)‖); MSE = V = eᵀe / N (the loss
det(E Eᵀ / N) of one output); FPE = V (1 + d/N) / (1 - d/N); nAIC = log V + 2d/N;
AIC = N log V + 2d + N (log 2π + 1); BIC = N log V + N (log 2π + 1) + d log N.
"""

import math
from dataclasses import asdict, dataclass

import numpy as np


@dataclass(frozen=True)
class FitMetrics:
    """Quality of one prediction of one record.

    Attributes:
        fit_percent: 100 (1 - ‖y - ŷ‖ / ‖y - mean(y)‖).
        mse: mean squared error, in the output's unit squared.
        fpe: Akaike's final prediction error.
        naic, aic, bic: normalised AIC, AIC and BIC.
        n: samples.
        parameters: d, the parameters counted in FPE and the information criteria.
    """

    fit_percent: float
    mse: float
    fpe: float
    naic: float
    aic: float
    bic: float
    n: int
    parameters: int

    def as_dict(self) -> dict:
        """The figures as a dict keyed by the attribute names."""
        return asdict(self)


def fit_percent(y: np.ndarray, y_hat: np.ndarray) -> float:
    """MATLAB's normalised root-mean-square fit, in percent (100 is perfect, may be negative)."""
    y, y_hat = np.asarray(y, float), np.asarray(y_hat, float)
    spread = np.linalg.norm(y - y.mean())
    if spread == 0:
        raise ValueError("fit_percent: the measured output is constant, so no fit is defined")
    return float(100.0 * (1.0 - np.linalg.norm(y - y_hat) / spread))


def evaluate_fit(y: np.ndarray, y_hat: np.ndarray, parameters: int) -> FitMetrics:
    """All figures for the prediction ``y_hat`` of ``y``.

    The model that made it has ``parameters`` estimated parameters (d in FPE and the criteria).
    """
    y, y_hat = np.asarray(y, float), np.asarray(y_hat, float)
    if y.shape != y_hat.shape or y.ndim != 1 or y.size == 0:
        raise ValueError(
            f"evaluate_fit: y and y_hat must be non-empty 1-D arrays of one length, got "
            f"{y.shape} and {y_hat.shape}"
        )
    n, d = y.size, parameters
    loss = float(np.mean((y - y_hat) ** 2))
    log_loss = math.log(loss) if loss > 0 else -math.inf
    return FitMetrics(
        fit_percent=fit_percent(y, y_hat),
        mse=loss,
        fpe=loss * (1 + d / n) / (1 - d / n) if d < n else math.inf,
        naic=log_loss + 2 * d / n,
        aic=n * log_loss + 2 * d + n * (math.log(2 * math.pi) + 1),
        bic=n * log_loss + n * (math.log(2 * math.pi) + 1) + d * math.log(n),
        n=n,
        parameters=d,
    )
