"""What a fitted model makes of one part of a record: its predictions, its residuals' correlations.

The report's figures and the compare and residual plots read curves made by the one function
here, with the initial states the report's module docstring states. Light to import (numpy only),
so a plotting process can receive the curves without importing the estimators.
"""

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from maskless.analysis.identification.residual_analysis import (
    ResidualCorrelations,
    residual_correlations,
)

if TYPE_CHECKING:  # annotations only: report imports the estimators (scipy)
    from maskless.analysis.identification.report import FittedModel, Part


@dataclass(frozen=True)
class PartCurves:
    """A model's curves on one part.

    Attributes:
        name: the part's name ("estimation", "validation").
        measured: the part's output (N,), detrended.
        one_step: the one-step-ahead prediction (N,).
        simulated: the output simulated from the input alone (N,).
        correlations: the one-step residuals' correlations, one per input (the autocorrelation
            is the same in each).
    """

    name: str
    measured: np.ndarray
    one_step: np.ndarray
    simulated: np.ndarray
    correlations: tuple[ResidualCorrelations, ...]


def initial_state_for_part(fitted: "FittedModel", part: "Part", estimation: "Part", horizon: str):
    """The x(0) a figure uses: the estimated one on the estimation part's one-step figures.

    Elsewhere it is re-estimated for the ``horizon`` ("one_step" or "simulation") on ``part``,
    as MATLAB's ``compare`` does; zero where the fit did not estimate x(0).
    """
    model = fitted.polynomials
    if not fitted.estimated_initial_state:
        return np.zeros(model.order)
    if part is estimation and horizon == "one_step":
        return model.initial_state
    return model.initial_state_for(part.u, part.y, horizon)


def part_curves(fitted: "FittedModel", part: "Part", estimation: "Part") -> PartCurves:
    """The model's curves on ``part`` (``estimation``: the part it was fitted on)."""
    model = fitted.polynomials
    one_step = model.predict(
        part.u, part.y, initial_state_for_part(fitted, part, estimation, "one_step")
    )
    simulated = model.simulate(
        part.u, initial_state_for_part(fitted, part, estimation, "simulation")
    )
    inputs = [part.u] if part.u.ndim == 1 else list(part.u.T)
    correlations = tuple(residual_correlations(part.y - one_step, u) for u in inputs)
    return PartCurves(part.name, part.y, one_step, simulated, correlations)
