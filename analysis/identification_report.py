"""Fit models to a record and judge them: figures per part, the baselines, a verdict in words.

Every figure states its horizon and initial-state handling: "1step" is the one-step-ahead
prediction, "sim" the simulated output from the input alone; on the estimation part the initial
state is the estimated x(0) (or zero when not estimated); on any other part x(0) is re-estimated by
least squares for that horizon, as MATLAB's ``compare`` does.

The baselines a model must beat (shared/DESIGN.md): "next value = last value"; the same order with
no input (ARMA); and the free response of the estimated initial state alone.
"""

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from maskless.analysis.fit_metrics import evaluate_fit, fit_percent
from maskless.analysis.innovations_model import InnovationsModel
from maskless.analysis.prediction_error import estimate_arx, estimate_pem, parameter_count
from maskless.analysis.subspace import estimate_n4sid

METHODS = ("pem", "armax", "arx", "n4sid")

# Verdict thresholds, in fit points on the validation part (see ``verdict``).
_INPUT_ADDS_NOTHING_1STEP = 0.1
_INPUT_ADDS_NOTHING_SIM = 10.0
_EXPLAINS_SIM = 50.0


@dataclass(frozen=True)
class Part:
    """A named stretch of a detrended record."""

    name: str
    u: np.ndarray
    y: np.ndarray


@dataclass(frozen=True)
class FittedModel:
    """A model with how it was fitted."""

    method: str
    model: InnovationsModel
    estimated_initial_state: bool

    @property
    def parameters(self) -> int:
        return parameter_count(self.model, self.estimated_initial_state)


def fit(
    method: str,
    part: Part,
    order: int,
    sample_period_s: float,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
) -> FittedModel:
    """Fits one model: "pem" (innovations-form state space) and "armax" (the same model set,
    ARMAX(n, n, n)) by prediction error, "arx" by least squares (zero initial state), "n4sid" by
    subspace identification (PO-MOESP)."""
    if method in ("pem", "armax"):
        model = estimate_pem(
            part.u,
            part.y,
            order,
            sample_period_s,
            estimate_initial_state=estimate_initial_state,
            progress=progress,
        )
        return FittedModel(method, model, estimate_initial_state)
    if method == "arx":
        return FittedModel(method, estimate_arx(part.u, part.y, order, sample_period_s), False)
    if method == "n4sid":
        model, _ = estimate_n4sid(
            part.u, part.y, order, sample_period_s, estimate_initial_state=estimate_initial_state
        )
        return FittedModel(method, model, estimate_initial_state)
    raise ValueError(f"method = {method!r}: expected one of {', '.join(METHODS)}")


def _initial_state(fitted: FittedModel, part: Part, estimation: Part, horizon: str):
    model = fitted.model
    if not fitted.estimated_initial_state:
        return np.zeros(model.order)
    if part is estimation and horizon == "one_step":
        return model.initial_state
    return model.initial_state_for(part.u, part.y, horizon)


def part_figures(
    fitted: FittedModel, part: Part, estimation: Part, k_step: int | None = None
) -> dict:
    """fit_percent_1step, fit_percent_sim, mse, fpe, naic, aic, bic and n of one part, and
    fit_percent_{k}step when ``k_step`` is given (from zero initial conditions); the error figures
    are those of the one-step prediction."""
    model = fitted.model
    one_step = model.predict(part.u, part.y, _initial_state(fitted, part, estimation, "one_step"))
    simulated = model.simulate(part.u, _initial_state(fitted, part, estimation, "simulation"))
    metrics = evaluate_fit(part.y, one_step, fitted.parameters)
    figures = {
        "fit_percent_1step": metrics.fit_percent,
        "fit_percent_sim": fit_percent(part.y, simulated),
        "mse": metrics.mse,
        "fpe": metrics.fpe,
        "naic": metrics.naic,
        "aic": metrics.aic,
        "bic": metrics.bic,
        "n": metrics.n,
    }
    if k_step is not None:
        k_ahead = model.predict_k_steps(part.u, part.y, k_step)
        # The first k samples have no k-step prediction from data.
        figures[f"fit_percent_{k_step}step"] = fit_percent(part.y[k_step:], k_ahead[k_step:])
    return figures


def baseline_figures(fitted: FittedModel, parts: list[Part]) -> dict:
    """The same-order ARMA's one-step fit and the initial state's free-response fit, per part."""
    estimation = parts[0]
    model = fitted.model
    arma = FittedModel(
        "arma",
        estimate_pem(
            estimation.u,
            estimation.y,
            model.order,
            model.sample_period_s,
            estimate_initial_state=fitted.estimated_initial_state,
            with_input=False,
            initial_model=model,
        ),
        fitted.estimated_initial_state,
    )
    figures = {"order": model.order, "method": fitted.method, "arma": {}, "free_response": {}}
    for part in parts:
        x0 = _initial_state(arma, part, estimation, "one_step")
        figures["arma"][part.name] = {
            "fit_percent_1step": fit_percent(part.y, arma.model.predict(part.u, part.y, x0))
        }
        x0 = _initial_state(fitted, part, estimation, "simulation")
        figures["free_response"][part.name] = {
            "fit_percent_sim": fit_percent(part.y, model.free_response(part.y.size, x0))
        }
    return figures


def naive_figures(parts: list[Part]) -> dict:
    """'Next value = last value': ŷ(k) = y(k-1), per part."""
    return {p.name: {"fit_percent_1step": fit_percent(p.y[1:], p.y[:-1])} for p in parts}


def verdict(figures: dict, baselines: dict, part_name: str) -> str:
    """Whether the input explains the output, in plain words, from one part's figures.

    The input "explains essentially nothing" when dropping it costs less than 0.1 points of
    one-step fit and the input-driven simulation fits less than 10 points better than the initial
    state alone; it "explains the output" when that simulation fits at least 50 %.
    """
    model_1step = figures["fit_percent_1step"]
    arma_1step = baselines["arma"][part_name]["fit_percent_1step"]
    simulated = figures["fit_percent_sim"]
    free = baselines["free_response"][part_name]["fit_percent_sim"]
    order = baselines["order"]
    evidence = (
        f"without the input the same order-{order} structure predicts one step ahead "
        f"{arma_1step:.3f} % against {model_1step:.3f} %, and the model driven by the input alone "
        f"fits the {part_name} part {simulated:.1f} % ({free:.1f} % from its initial state alone)"
    )
    if model_1step - arma_1step < _INPUT_ADDS_NOTHING_1STEP and (
        simulated - free < _INPUT_ADDS_NOTHING_SIM
    ):
        return f"The input explains essentially nothing of the output: {evidence}."
    if simulated >= _EXPLAINS_SIM:
        return f"The input explains the output: {evidence}."
    return f"The input explains part of the output: {evidence}."


def beats_baselines(figures: dict, baselines: dict, naive: dict, part_name: str) -> dict:
    """Whether the model does better than each baseline on one part (one-step fit against the
    naive predictor and the ARMA, simulation fit against the initial state's free response)."""
    return {
        "naive_last_value": figures["fit_percent_1step"] > naive[part_name]["fit_percent_1step"],
        "arma": figures["fit_percent_1step"] > baselines["arma"][part_name]["fit_percent_1step"],
        "free_response": figures["fit_percent_sim"]
        > baselines["free_response"][part_name]["fit_percent_sim"],
    }


def identify(
    method: str,
    estimation: Part,
    validation: Part,
    orders: list[int],
    sample_period_s: float,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
    k_step: int | None = None,
) -> tuple[dict, list[FittedModel]]:
    """Fits each order and builds the report (the JSON of `maskless identify`)."""
    parts = [estimation, validation]
    entries, fitted_models, baselines = [], [], []
    for order in orders:
        fitted = fit(method, estimation, order, sample_period_s, estimate_initial_state, progress)
        model = fitted.model
        figures = {part.name: part_figures(fitted, part, estimation, k_step) for part in parts}
        model_baselines = baseline_figures(fitted, parts)
        matrices = model.state_space()
        entry = {
            "method": method,
            "order": order,
            "ts": sample_period_s,
            **{name: matrix.tolist() for name, matrix in matrices.items()},
            "initial_state": "estimated" if fitted.estimated_initial_state else "zero",
            "parameters": fitted.parameters,
            "poles": _complex_list(model.poles()),
            "stable": model.is_stable(),
            "predictor_stable": bool(np.all(np.abs(model.predictor_poles()) < 1)),
            "dc_gain": model.dc_gain(),
            **figures,
            "verdict": verdict(figures[validation.name], model_baselines, validation.name),
            "beats_on_validation": beats_baselines(
                figures[validation.name],
                model_baselines,
                naive_figures([validation]),
                validation.name,
            ),
        }
        if method == "armax":
            entry["polynomials"] = {
                "A": [1.0, *model.a.tolist()],
                "B": [0.0, *model.b.tolist()],
                "C": [1.0, *model.c.tolist()],
            }
        if not entry["stable"]:
            entry["warning"] = (
                f"the order-{order} model is unstable (largest pole magnitude "
                f"{np.abs(model.poles()).max():.6f}); do not design a controller on it"
            )
        entries.append(entry)
        fitted_models.append(fitted)
        baselines.append(model_baselines)
    best = max(entries, key=lambda e: e[validation.name]["fit_percent_1step"])
    report = {
        "horizons": {
            "1step": "one-step-ahead prediction",
            "sim": "simulation from the input alone",
            "kstep": "k-step-ahead prediction from zero initial conditions (with --k-step)",
            "initial_state": "estimated x(0) on the estimation part; re-estimated by least "
            "squares for each horizon on the validation part",
        },
        "models": entries,
        "baselines": {"naive_last_value": naive_figures(parts), "per_model": baselines},
        "verdict": best["verdict"],
    }
    return report, fitted_models


def _complex_list(values: np.ndarray) -> list:
    return [[float(v.real), float(v.imag)] for v in values]
