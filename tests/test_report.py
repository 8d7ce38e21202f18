"""The report's margins and verdict against their documented thresholds, on hand-built figures."""

import math

import numpy as np
import pytest

from maskless.analysis.identification.innovations_model import InnovationsModel
from maskless.analysis.identification.report import (
    EXPLAINS_SIM,
    EXPLAINS_VERDICT,
    MARGIN_1STEP,
    MARGIN_SIM,
    NO_VERDICT,
    FittedModel,
    Part,
    fit,
    instability,
    margins,
    model_entry,
    naive_figures,
    verdict,
)

PART = "validation"
EXPLAINS = EXPLAINS_VERDICT
NOTHING = "The input explains essentially nothing of the output"
PARTLY = "The input explains part of the output"


def baselines(without_input_1step=89.0, free_response_sim=5.0):
    """The shape ``baseline_figures`` returns, for one part."""
    return {
        "order": 2,
        "method": "pem",
        "without_input_structure": "arma",
        "without_input": {PART: {"fit_percent_1step": without_input_1step}},
        "free_response": {PART: {"fit_percent_sim": free_response_sim}},
    }


def judge(sim, without_input, free_response, unstable=None):
    """The verdict on a part whose simulation fits ``sim`` % with the given margins (points)."""
    figures = {"fit_percent_1step": 90.0, "fit_percent_sim": sim}
    gains = {
        "naive_last_value": 1.0,
        "without_input": without_input,
        "free_response": free_response,
    }
    return verdict(figures, baselines(), gains, PART, unstable)


def test_margins_are_the_fit_points_won_over_each_baseline():
    # Binary fractions, so the differences are exact.
    figures = {"fit_percent_1step": 95.5, "fit_percent_sim": 62.25}
    naive = {PART: {"fit_percent_1step": 90.25}}
    gains = margins(figures, baselines(95.0, 12.5), naive, PART)
    assert gains == {"naive_last_value": 5.25, "without_input": 0.5, "free_response": 49.75}


def test_a_model_that_loses_has_negative_margins():
    figures = {"fit_percent_1step": 80.0, "fit_percent_sim": 20.0}
    naive = {PART: {"fit_percent_1step": 85.0}}
    gains = margins(figures, baselines(82.5, 30.0), naive, PART)
    assert gains == {"naive_last_value": -5.0, "without_input": -2.5, "free_response": -10.0}


@pytest.mark.parametrize(
    "free_response_sim, margin",
    [(-30.0, 40.0), (-1e-9, 40.0), (0.0, 40.0), (0.25, 39.75)],
)
def test_a_free_response_worse_than_zero_is_no_baseline(free_response_sim, margin):
    # "A transient that fits worse than zero is no baseline to beat": the margin is over max(., 0).
    figures = {"fit_percent_1step": 90.0, "fit_percent_sim": 40.0}
    naive = {PART: {"fit_percent_1step": 80.0}}
    gains = margins(figures, baselines(89.0, free_response_sim), naive, PART)
    assert gains["free_response"] == margin


def test_documented_thresholds():
    # "at least 50 %", "by 10 points", "less than 0.1 points" (the verdict's docstring).
    assert (EXPLAINS_SIM, MARGIN_SIM, MARGIN_1STEP) == (50.0, 10.0, 0.1)


# Just across a threshold: the next float below it.
BELOW_50 = math.nextafter(50.0, 0.0)
BELOW_10 = math.nextafter(10.0, 0.0)
BELOW_0_1 = math.nextafter(0.1, 0.0)


@pytest.mark.parametrize(
    "sim, without_input, free_response, expected",
    [
        # Explains: simulation fit >= 50 % and >= 10 points over the free response, whatever
        # dropping the input costs the one-step fit.
        (50.0, 5.0, 10.0, EXPLAINS),
        (50.0, 0.0, 10.0, EXPLAINS),
        (99.0, -1.0, 60.0, EXPLAINS),
        (BELOW_50, 5.0, 10.0, PARTLY),
        (50.0, 5.0, BELOW_10, PARTLY),
        # Nothing: dropping the input costs < 0.1 points and the simulation is < 10 points over.
        (BELOW_50, BELOW_0_1, BELOW_10, NOTHING),
        (80.0, -3.0, -20.0, NOTHING),
        (BELOW_50, 0.1, BELOW_10, PARTLY),
        (BELOW_50, BELOW_0_1, 10.0, PARTLY),
        (80.0, BELOW_0_1, BELOW_10, NOTHING),  # a good fit that the free response makes too
    ],
)
def test_verdict_at_and_just_across_each_threshold(sim, without_input, free_response, expected):
    words = judge(sim, without_input, free_response)
    assert words.startswith(f"{expected}: ")
    assert "UNSTABLE" not in words


def test_verdict_gives_its_evidence_and_flags_an_unstable_model():
    words = judge(62.0, 1.0, 57.0, unstable="its one-step predictor (largest root of C(z) 1.1)")
    assert words.startswith(f"{EXPLAINS}: ")  # the judgement is the same
    assert "order-2 structure (ARMA)" in words and f"the {PART} part" in words
    assert "89.000 % against 90.000 %" in words  # without the input, and with it
    assert "62.0 % (5.0 % from its initial state alone)" in words
    assert words.endswith(
        "; the model is UNSTABLE: its one-step predictor (largest root of C(z) 1.1)."
    )


def polynomials(poles, predictor_poles):
    """An order-2 model whose A(z) and C(z) have the given roots."""
    a = np.real(np.poly(poles))[1:]
    c = np.real(np.poly(predictor_poles))[1:]
    return InnovationsModel(
        a=a, b=np.array([1.0, 0.5]), k=c - a, sample_period_s=1.0, initial_state=np.zeros(2)
    )


@pytest.mark.parametrize(
    "poles, predictor_poles, expected",
    [
        ([0.9, 0.5], [0.3, 0.2], None),
        ([1.05, 0.5], [0.3, 0.2], "its system (largest pole magnitude 1.050000)"),
        ([0.9, 0.5], [0.3, -1.2], "its one-step predictor (largest root of C(z) 1.200000)"),
        (
            [0.9, 1.02],
            [0.3, 1.01],
            "its system (largest pole magnitude 1.020000) and its one-step predictor "
            "(largest root of C(z) 1.010000)",
        ),
    ],
)
def test_instability_names_the_unstable_system_and_predictor(poles, predictor_poles, expected):
    assert instability(polynomials(poles, predictor_poles)) == expected


def entry_of(model):
    """``model_entry`` of ``model`` as a PEM fit, on hand-built figures."""
    fitted = FittedModel("pem", model.linear_model(), model, True, 8)
    figures = {PART: {"fit_percent_1step": 90.0, "fit_percent_sim": 62.0}}
    gains = {"naive_last_value": 1.0, "without_input": 1.0, "free_response": 57.0}
    return model_entry(fitted, figures, baselines(), gains, PART)


def test_an_unstable_predictor_is_warned_about_and_judged_unstable():
    # Before issue 14 `predictor_stable: false` was computed, and neither the warning nor the
    # verdict used it.
    entry = entry_of(polynomials([0.9, 0.5], [0.3, 1.2]))
    assert entry["stable"] and not entry["predictor_stable"]
    assert entry["warning"].startswith("the order-2 pem model is unstable: its one-step predictor")
    assert entry["verdict"].endswith("(largest root of C(z) 1.200000).")


def test_a_stable_model_has_no_warning():
    entry = entry_of(polynomials([0.9, 0.5], [0.3, 0.2]))
    assert entry["stable"] and entry["predictor_stable"] and "warning" not in entry
    assert "UNSTABLE" not in entry["verdict"]


def test_naive_figures_fit_last_value_predictions():
    # ŷ(k) = y(k-1). On the ramp 1..5: errors all 1 over 4 samples (norm 2), the spread of
    # 2..5 about 3.5 is sqrt(5): fit 100 (1 - 2 / sqrt(5)). On 0, 2, 0, 2: errors all 2 (norm
    # sqrt(12)) against a spread sqrt(24 / 9) of 2, 0, 2 about 4/3.
    parts = [
        Part("ramp", np.zeros(5), np.arange(1.0, 6.0)),
        Part("zigzag", np.zeros(4), np.array([0.0, 2, 0, 2])),
    ]
    figures = naive_figures(parts)
    assert figures["ramp"]["fit_percent_1step"] == pytest.approx(100 * (1 - 2 / math.sqrt(5)))
    assert figures["zigzag"]["fit_percent_1step"] == pytest.approx(
        100 * (1 - math.sqrt(12) / math.sqrt(24 / 9))
    )


def test_an_unknown_method_is_refused_naming_the_methods():
    part = Part("estimation", np.zeros(100), np.zeros(100))
    with pytest.raises(ValueError, match="method = 'ols': expected one of pem, armax, arx, n4sid"):
        fit("ols", part, 2, 1.0)


def test_a_nan_figure_is_named_not_judged():
    figures = {"fit_percent_1step": 90.0, "fit_percent_sim": math.nan}
    gains = {"naive_last_value": 1.0, "without_input": 5.0, "free_response": math.nan}
    said = verdict(figures, baselines(), gains, PART, unstable=None)
    assert said == f"{NO_VERDICT}: on the validation part, fit_percent_sim is NaN."
    said = verdict(figures, baselines(), gains, PART, unstable="its system (...)")
    assert said.endswith("fit_percent_sim is NaN; the model is UNSTABLE: its system (...).")
