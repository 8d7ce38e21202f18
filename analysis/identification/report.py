"""Fit models to a record and judge them: figures per part, the baselines, a verdict in words.

Every figure states its horizon and initial-state handling (the report's "horizons" entry says
which were used): "1step" is the one-step-ahead prediction, "sim" the simulated output from the
input alone, "kstep" the k-step-ahead prediction (from zero initial conditions). When the initial
state is estimated, the one-step figures on the estimation part use the estimated x(0); every other
part and horizon re-estimates x(0) by least squares for that horizon, as MATLAB's ``compare`` does.

The baselines a model must beat (shared/DESIGN.md): "next value = last value"; the same structure
with no input (ARMA for the noise-model methods, AR for ARX); and the free response of the
estimated initial state alone.

A part whose input has m columns (the inlet and the outlet valve) gets an m-input model; its entry
then says, per input, the DC gain and what the input contributes (``input_contributions``), and
the diagnostics are per input, with whether the inputs can be told apart (``input_diagnostics``).
"""

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from maskless.analysis.identification import METHODS, data_diagnostics
from maskless.analysis.identification.fit_metrics import evaluate_fit, fit_percent
from maskless.analysis.identification.innovations_model import InnovationsModel
from maskless.analysis.identification.input_diagnostics import diagnose_inputs
from maskless.analysis.identification.part_curves import (
    PartCurves,
    initial_state_for_part,
    part_curves,
)
from maskless.analysis.identification.prediction_error import (
    estimate_ar,
    estimate_arx,
    estimate_pem,
    parameter_count,
)
from maskless.analysis.identification.records import OVERLAPPING_PARTS_WARNING
from maskless.analysis.identification.subspace import HORIZON_RULE, estimate_n4sid
from maskless.errors import ModelError
from maskless.systems.linear_model import LinearModel, stable

# The verdict's thresholds, in fit points on the validation part. They are conventions, not
# derived values: 0.1 points is ten times the precision of the fits in the paper's Table I; a
# simulation must beat the better of zero and the initial state's transient by 10 points to count
# as input-driven; and 50 % simulation fit is where the input carries most of the output.
MARGIN_1STEP = 0.1
MARGIN_SIM = 10.0
EXPLAINS_SIM = 50.0


@dataclass(frozen=True)
class Part:
    """A named stretch of a detrended record: u (N,) for one input, (N, m) for m inputs."""

    name: str
    u: np.ndarray
    y: np.ndarray


@dataclass(frozen=True)
class FittedModel:
    """A model with how it was fitted.

    Attributes:
        method: the estimator.
        model: the identified model, identification's result: innovations form with K and the
            one-step innovations variance on the estimation part, of the detrended record's
            deviations in its units (the model file adds the offsets and units). None for an
            m-input model, which the single-input ``LinearModel`` cannot hold: see
            ``input_models``.
        polynomials: the same model as the estimator's coefficients (a, b, k), with the x(0)
            estimated on the estimation part; it runs the figures' predictions.
        estimated_initial_state: whether x(0) was estimated.
        parameters: d, the estimated parameters (initial states included when estimated).
        details: what else the estimator reports (e.g. N4SID's horizon and singular values).
        input_models: per input, the single-input model from that input (the others held at
            their operating points), with the whole model's K and variance; (model,) for one.
        curves: its curves on each part it was judged on (``identify`` sets them; the report's
            figures and the plots both read them); empty before.
    """

    method: str
    model: LinearModel | None
    polynomials: InnovationsModel
    estimated_initial_state: bool
    parameters: int
    details: dict = field(default_factory=dict)
    input_models: tuple[LinearModel, ...] = ()
    curves: tuple[PartCurves, ...] = ()

    @property
    def linear_models(self) -> tuple[LinearModel, ...]:
        """One ``LinearModel`` per input: ``input_models``, or (``model``,) when not given."""
        return self.input_models or (self.model,)

    @property
    def order(self) -> int:
        """n, the model's number of states."""
        return self.linear_models[0].order


def _fitted_model(
    method: str,
    polynomials: InnovationsModel,
    estimation: Part,
    estimated_initial_state: bool,
    parameters: int,
    details: dict | None = None,
) -> FittedModel:
    """``polynomials`` fitted on ``estimation`` as a FittedModel.

    Its model carries the variance of the one-step innovations on ``estimation``.
    """
    # Every estimator leaves x(0) at zero when it does not estimate it, so the model's own x(0) is
    # the one the estimation part's one-step figures use.
    innovations = estimation.y - polynomials.predict(estimation.u, estimation.y)
    variance = float(np.mean(innovations**2))
    input_models = tuple(
        polynomials.linear_model(variance, input_index=i) for i in range(polynomials.inputs)
    )
    return FittedModel(
        method=method,
        model=input_models[0] if polynomials.b.ndim == 1 else None,
        polynomials=polynomials,
        estimated_initial_state=estimated_initial_state,
        parameters=parameters,
        details=details or {},
        input_models=input_models,
    )


def fit(
    method: str,
    part: Part,
    order: int,
    sample_period_s: float,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
    input_names: tuple[str, ...] | None = None,
) -> FittedModel:
    """Fits one model of ``order`` to ``part`` by ``method``.

    "pem" (innovations-form state space) and "armax" (the same model set, ARMAX(n, n, n)) fit by
    prediction error, "arx" by least squares (zero initial state), "n4sid" by subspace
    identification (PO-MOESP). A part with m input columns gets an m-input model, whose
    ``details["input_names"]`` are ``input_names``.
    """
    fitted = _fit(method, part, order, sample_period_s, estimate_initial_state, progress)
    if part.u.ndim == 1:
        return fitted
    names = input_names or tuple(f"input {i + 1}" for i in range(part.u.shape[1]))
    return replace(fitted, details={**fitted.details, "input_names": list(names)})


def _fit(method, part, order, sample_period_s, estimate_initial_state, progress) -> FittedModel:
    """``fit`` without the input names."""
    count = parameter_count(
        order,
        with_input=True,
        with_noise_model=method != "arx",
        estimated_initial_state=estimate_initial_state and method != "arx",
        inputs=1 if part.u.ndim == 1 else part.u.shape[1],
    )
    if method in ("pem", "armax"):
        polynomials = estimate_pem(
            part.u,
            part.y,
            order,
            sample_period_s,
            estimate_initial_state=estimate_initial_state,
            progress=progress,
        )
        return _fitted_model(method, polynomials, part, estimate_initial_state, count)
    if method == "arx":
        polynomials = estimate_arx(part.u, part.y, order, sample_period_s)
        return _fitted_model(method, polynomials, part, False, count)
    if method == "n4sid":
        subspace = estimate_n4sid(
            part.u,
            part.y,
            order,
            sample_period_s,
            estimate_initial_state=estimate_initial_state,
            progress=progress,
        )
        details = {
            "horizon": {
                "past": subspace.past_horizon,
                "future": subspace.future_horizon,
                "rule": HORIZON_RULE,
            },
            "singular_values": subspace.singular_values[: 2 * order + 2].tolist(),
        }
        return _fitted_model(method, subspace.model, part, estimate_initial_state, count, details)
    raise ValueError(f"method = {method!r}: expected one of {', '.join(METHODS)}")


def part_figures(
    fitted: FittedModel, part: Part, curves: PartCurves, k_step: int | None = None
) -> dict:
    """The figures of one part: its fits, its error figures and its residuals' whiteness.

    fit_percent_1step, fit_percent_sim, mse, fpe, naic, aic, bic and n, and fit_percent_{k}step
    when ``k_step`` is given; the error figures are those of the one-step prediction. The
    whiteness is the share of lags outside the 99 % bands. ``curves``: the model's on ``part``
    (``part_curves``).
    """
    model = fitted.polynomials
    one_step, simulated = curves.one_step, curves.simulated
    metrics = evaluate_fit(part.y, one_step, fitted.parameters)
    # An unstable system's simulation overflows on a long part: its fit is then -inf or NaN
    # (inf - inf), which the verdict names, rather than a numpy warning.
    with np.errstate(over="ignore", invalid="ignore"):
        simulation_fit = fit_percent(part.y, simulated)
    figures = {
        "fit_percent_1step": metrics.fit_percent,
        "fit_percent_sim": simulation_fit,
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
    if part.u.ndim == 1:
        figures["residuals_outside_99_percent_band"] = curves.correlations[0].fraction_outside()
        return figures
    # With m inputs the residuals' whiteness is one figure, their independence one per input.
    per_input = [correlations.fraction_outside() for correlations in curves.correlations]
    figures["residuals_outside_99_percent_band"] = {
        "autocorrelation": per_input[0]["autocorrelation"],
        "cross_correlation_per_input": [shares["cross_correlation"] for shares in per_input],
    }
    return figures


def input_contributions(
    fitted: FittedModel, part: Part, estimation: Part, names: tuple[str, ...]
) -> dict:
    """What each input of an m-input model contributes on ``part``, by input name.

    Per input: its DC gain (output unit per its unit; None for an integrating model); the
    simulation fit with that input alone (the others at their operating points) and with it
    removed, from the whole simulation's x(0); the fit points lost without it; and the share of the
    output's variance about its mean that its own simulated part (from x(0) = 0) carries. An input
    whose removal costs nothing explains nothing the others do not.
    """
    model = fitted.polynomials
    x0 = initial_state_for_part(fitted, part, estimation, "simulation")
    with np.errstate(over="ignore", invalid="ignore"):  # as in part_figures
        whole = fit_percent(part.y, model.simulate(part.u, x0))
        contributions = {}
        for index, (name, single) in enumerate(zip(names, fitted.input_models, strict=True)):
            alone, without = np.zeros_like(part.u), part.u.copy()
            alone[:, index], without[:, index] = part.u[:, index], 0.0
            fit_without = fit_percent(part.y, model.simulate(without, x0))
            own = model.simulate(alone, np.zeros(model.order))
            contributions[name] = {
                "dc_gain": _dc_gain(single),
                "fit_percent_sim_alone": fit_percent(part.y, model.simulate(alone, x0)),
                "fit_percent_sim_without": fit_without,
                "fit_points_lost_without": whole - fit_without,
                "output_variance_share": float(np.var(own) / np.var(part.y)),
            }
    return contributions


def baseline_figures(fitted: FittedModel, parts: list[Part], progress=None) -> dict:
    """Per part, the one-step fit without input and the simulation fit of the free response.

    The first is the same structure fitted without input, the second the initial state's free
    response.
    """
    estimation = parts[0]
    model = fitted.polynomials
    if fitted.method == "arx":
        ar = estimate_ar(estimation.y, model.order, model.sample_period_s)
        ar = replace(ar, b=np.zeros_like(model.b))  # as many (zero) inputs as the model
        without_input = _fitted_model("ar", ar, estimation, False, 0)
    else:
        arma = estimate_pem(
            estimation.u,
            estimation.y,
            model.order,
            model.sample_period_s,
            estimate_initial_state=fitted.estimated_initial_state,
            with_input=False,
            initial_model=model,  # estimate_pem zeroes b without input
            progress=progress,
        )
        without_input = _fitted_model("arma", arma, estimation, fitted.estimated_initial_state, 0)
    figures = {
        "order": model.order,
        "method": fitted.method,
        "without_input_structure": without_input.method,
        "without_input": {},
        "free_response": {},
    }
    for part in parts:
        x0 = initial_state_for_part(without_input, part, estimation, "one_step")
        figures["without_input"][part.name] = {
            "fit_percent_1step": fit_percent(
                part.y, without_input.polynomials.predict(part.u, part.y, x0)
            )
        }
        x0 = initial_state_for_part(fitted, part, estimation, "simulation")
        with np.errstate(over="ignore", invalid="ignore"):  # as in part_figures
            free_response_fit = fit_percent(part.y, model.free_response(part.y.size, x0))
        figures["free_response"][part.name] = {"fit_percent_sim": free_response_fit}
    return figures


def naive_figures(parts: list[Part]) -> dict:
    """'Next value = last value': ŷ(k) = y(k-1), per part."""
    return {p.name: {"fit_percent_1step": fit_percent(p.y[1:], p.y[:-1])} for p in parts}


def margins(figures: dict, baselines: dict, naive: dict, part_name: str) -> dict:
    """By how many fit points the model beats each baseline on one part (negative: it loses)."""
    return {
        "naive_last_value": figures["fit_percent_1step"] - naive[part_name]["fit_percent_1step"],
        "without_input": figures["fit_percent_1step"]
        - baselines["without_input"][part_name]["fit_percent_1step"],
        # A transient that fits worse than zero is no baseline to beat.
        "free_response": figures["fit_percent_sim"]
        - max(baselines["free_response"][part_name]["fit_percent_sim"], 0.0),
    }


# How a verdict that the input explains the output begins (the workflow checks for it).
EXPLAINS_VERDICT = "The input explains the output"
# How a verdict that it explains part of it begins.
EXPLAINS_PART_VERDICT = "The input explains part of the output"
# How a verdict begins when a figure it needs is undefined (NaN): it is named, not judged.
NO_VERDICT = "No verdict"


def instability(polynomials: InnovationsModel) -> str | None:
    """What is unstable in a model, in words: its system, its one-step predictor, or both.

    None when both are stable. The predictor's poles are the roots of C(z); an unstable one
    makes every one-step figure and Kalman filter built on the model diverge.
    """
    unstable = []
    if not stable(polynomials.poles()):
        largest = np.abs(polynomials.poles()).max()
        unstable.append(f"its system (largest pole magnitude {largest:.6f})")
    if not stable(polynomials.predictor_poles()):
        largest = np.abs(polynomials.predictor_poles()).max()
        unstable.append(f"its one-step predictor (largest root of C(z) {largest:.6f})")
    return " and ".join(unstable) or None


def verdict(
    figures: dict, baselines: dict, gains: dict, part_name: str, unstable: str | None
) -> str:
    """Whether the input explains the output, in plain words, judged on one part.

    The judgement uses that part's figures and the model's ``margins`` over the baselines on it;
    ``unstable`` (``instability``'s words, None for a stable model) is said at the end in
    capitals.

    "explains the output": the input-driven simulation fits at least 50 % and beats the initial
    state's free response (or zero) by 10 points. "essentially nothing": dropping the input costs
    less than 0.1 points of one-step fit and the simulation does not beat the free response (or
    zero) by 10 points. Otherwise "part of the output". A NaN among the figures judged gives
    no verdict: the message names it.
    """
    judged = {
        "fit_percent_1step": figures["fit_percent_1step"],
        "fit_percent_sim": figures["fit_percent_sim"],
        "without_input fit_percent_1step": baselines["without_input"][part_name][
            "fit_percent_1step"
        ],
        "free_response fit_percent_sim": baselines["free_response"][part_name]["fit_percent_sim"],
    }
    warning = f"; the model is UNSTABLE: {unstable}" if unstable else ""
    undefined = [name for name, value in judged.items() if np.isnan(value)]
    if undefined:
        # NaN compares false with everything, so a threshold would pass a verdict on nothing.
        return (
            f"{NO_VERDICT}: on the {part_name} part, {', '.join(undefined)} "
            f"{'is' if len(undefined) == 1 else 'are'} NaN{warning}."
        )
    structure, order = baselines["without_input_structure"].upper(), baselines["order"]
    evidence = (
        f"without the input the same order-{order} structure ({structure}) predicts one step "
        f"ahead {baselines['without_input'][part_name]['fit_percent_1step']:.3f} % against "
        f"{figures['fit_percent_1step']:.3f} %, and the model driven by the input alone fits the "
        f"{part_name} part {figures['fit_percent_sim']:.1f} % "
        f"({baselines['free_response'][part_name]['fit_percent_sim']:.1f} % from its initial "
        f"state alone){warning}"
    )
    if figures["fit_percent_sim"] >= EXPLAINS_SIM and gains["free_response"] >= MARGIN_SIM:
        return f"{EXPLAINS_VERDICT}: {evidence}."
    if gains["without_input"] < MARGIN_1STEP and gains["free_response"] < MARGIN_SIM:
        return f"The input explains essentially nothing of the output: {evidence}."
    return f"{EXPLAINS_PART_VERDICT}: {evidence}."


def identify(
    method: str,
    estimation: Part,
    validation: Part,
    orders: list[int],
    sample_period_s: float,
    estimate_initial_state: bool = True,
    progress: Callable[[int, float], None] | None = None,
    k_step: int | None = None,
    overlap: bool = False,
    record_diagnostics: data_diagnostics.RecordDiagnostics
    | tuple[data_diagnostics.RecordDiagnostics, ...]
    | None = None,
    input_names: tuple[str, ...] | None = None,
    record_warnings: tuple[str, ...] = (),
) -> tuple[dict, list[FittedModel]]:
    """Fits each order and builds the report (the JSON of `maskless identify`).

    Args:
        method: the estimator: "pem", "armax", "arx" or "n4sid" (see ``fit``).
        estimation: the part the models are fitted on.
        validation: the part they are judged on: the report's verdict is that of the order with
            the best one-step fit there.
        orders: the model orders n, one model each.
        sample_period_s: Ts (s).
        estimate_initial_state: estimate x(0) too; "arx" always keeps x(0) = 0.
        progress: called as progress(evaluations, cost) during the prediction-error searches.
        k_step: k for the additional k-step-ahead fit; None for none.
        overlap: the validation part shares samples with the estimation part; the report and
            the verdict then say that the validation figures are not a holdout.
        record_diagnostics: the whole record's diagnostics (offsets, drift, holds, clipping),
            reported and warned with the parts' own (``data_diagnostics.diagnose``); with m
            inputs a tuple, one per input (``diagnose_record`` of that input and the output).
        input_names: with m inputs, their names (default "input 1", ...), keying the per-input
            figures; ignored for one input.
        record_warnings: what the reading of the record warned (a cut-off recording), first
            among the report's warnings and in the verdict.
    """
    parts = [estimation, validation]
    inputs = 1 if estimation.u.ndim == 1 else estimation.u.shape[1]
    if inputs > 1 and input_names is None:
        input_names = tuple(f"input {i + 1}" for i in range(inputs))
    if inputs > 1 and len(input_names) != inputs:
        raise ValueError(f"input_names = {input_names!r}: expected {inputs} names, one per input")
    entries, fitted_models, baselines = [], [], []
    naive = naive_figures(parts)
    for order in orders:
        fitted = fit(
            method,
            estimation,
            order,
            sample_period_s,
            estimate_initial_state,
            progress,
            input_names if inputs > 1 else None,
        )
        fitted = replace(fitted, curves=tuple(part_curves(fitted, p, estimation) for p in parts))
        figures = {
            part.name: part_figures(fitted, part, curves, k_step)
            for part, curves in zip(parts, fitted.curves, strict=True)
        }
        model_baselines = baseline_figures(fitted, parts, progress)
        gains = margins(figures[validation.name], model_baselines, naive, validation.name)
        entry = model_entry(fitted, figures, model_baselines, gains, validation.name)
        if inputs > 1:
            entry["input_contributions"] = {
                part.name: input_contributions(fitted, part, estimation, input_names)
                for part in parts
            }
        entries.append(entry)
        fitted_models.append(fitted)
        baselines.append(model_baselines)
    # A NaN fit would make max() depend on the order of the entries; it ranks last.
    best = max(
        entries, key=lambda e: np.nan_to_num(e[validation.name]["fit_percent_1step"], nan=-np.inf)
    )
    warnings = list(record_warnings)
    if overlap:
        warnings.append(OVERLAPPING_PARTS_WARNING)
    warnings += [entry["warning"] for entry in entries if "warning" in entry]
    # Data diagnostics (issue 14): the excitation, the fitted poles near 1, the record's own.
    poles_by_order = {m.order: m.linear_models[0].poles() for m in fitted_models}
    if inputs == 1:
        diagnostics = data_diagnostics.diagnose(estimation.u, poles_by_order, record_diagnostics)
    else:
        diagnostics = diagnose_inputs(estimation.u, poles_by_order, input_names, record_diagnostics)
    warnings += diagnostics.warnings
    initial = "estimated" if estimate_initial_state and method != "arx" else "zero"
    report = {
        "horizons": {
            "1step": "one-step-ahead prediction",
            "sim": "simulation from the input alone",
            **(
                {f"{k_step}step": f"{k_step}-step-ahead prediction from zero initial conditions"}
                if k_step
                else {}
            ),
            "initial_state": (
                "estimated x(0) for the one-step figures on the estimation part; re-estimated by "
                "least squares for every other part and horizon"
                if initial == "estimated"
                else "zero"
            ),
        },
        "models": entries,
        "baselines": {"naive_last_value": naive, "per_model": baselines},
        "warnings": warnings,
        "diagnostics": diagnostics.as_dict(),
        "verdict": best["verdict"] + "".join(f" Warning: {warning}." for warning in warnings),
    }
    return report, fitted_models


def model_entry(
    fitted: FittedModel, figures: dict, baselines: dict, gains: dict, part_name: str
) -> dict:
    """One model's entry in the report: the model, its figures, its verdict on ``part_name``.

    A model with an unstable system or one-step predictor gets a "warning" naming which, and
    its verdict says so.
    """
    polynomials = fitted.polynomials
    model = fitted.linear_models[0]  # A, C, K and the poles are every input's
    unstable = instability(polynomials)
    entry = {
        "method": fitted.method,
        "order": model.order,
        "ts": model.sample_period_s,
        **{name: getattr(model, name).tolist() for name in ("A", "B", "C", "D", "K")},
        "initial_state": "estimated" if fitted.estimated_initial_state else "zero",
        "parameters": fitted.parameters,
        "poles": [[float(p.real), float(p.imag)] for p in model.poles()],
        "stable": model.is_stable(),
        "predictor_stable": stable(polynomials.predictor_poles()),
        "dc_gain": _dc_gain(model),
        **fitted.details,
        **(_input_matrices(fitted) if fitted.model is None else {}),
        **figures,
        "margins_on_validation": gains,
        "verdict": verdict(figures[part_name], baselines, gains, part_name, unstable),
    }
    if fitted.method == "armax":
        entry["polynomials"] = {
            "A": [1.0, *polynomials.a.tolist()],
            "B": [0.0, *polynomials.b.tolist()]
            if polynomials.b.ndim == 1
            else [[0.0, *column] for column in polynomials.b.T.tolist()],
            "C": [1.0, *polynomials.c.tolist()],
        }
    if unstable:
        entry["warning"] = (
            f"the order-{model.order} {fitted.method} model is unstable: {unstable}; its "
            "figures diverge, so do not predict with it or design a controller on it"
        )
    return entry


def _input_matrices(fitted: FittedModel) -> dict:
    """An m-input model's B (n x m) and D (1 x m), and its DC gain per input (a list)."""
    return {
        "B": np.column_stack([single.B for single in fitted.input_models]).tolist(),
        "D": np.zeros((1, len(fitted.input_models))).tolist(),
        "dc_gain": [_dc_gain(single) for single in fitted.input_models],
    }


def _dc_gain(model: LinearModel) -> float | None:
    """The model's DC gain, or None (JSON null) for an integrating model, which has none."""
    try:
        return model.dc_gain()
    except ModelError:
        return None
