"""The population summary: figures against numpy on hand-made rows; failures count against."""

import numpy as np
import pytest

from maskless.analysis.population_summary import summarize_population, summary_table


def row(trial, controller="c", p95=0.5, within=1.0, settle=3.0, error=None, reachable=True):
    return {
        "trial": trial,
        "run": 0,
        "controller": controller,
        "reachable": reachable,
        "p95_abs_error_mm": p95,
        "max_abs_error_mm": None if p95 is None else 2 * p95,
        "rms_error_mm": None if p95 is None else p95 / 2,
        "time_within_tolerance_fraction": within,
        "settle_time_s": settle,
        "overshoot_mm": 0.1 * trial,
        "error": error,
    }


def failed(trial):
    return row(trial, p95=None, within=None, settle=None, error="RuntimeError: x")


def test_figures_are_numpys_over_every_trial():
    p95 = np.linspace(0.2, 2.0, 10)
    rows = [
        row(k, p95=v, within=1 - v / 4, settle=None if v > 1.5 else v) for k, v in enumerate(p95)
    ]
    figures = summarize_population(rows, ["c"], 0.001)["per_controller"]["c"]
    assert figures["runs"] == 10 and figures["failed"] == 0
    assert figures["p95_within_tolerance_fraction"] == np.mean(p95 <= 1.0)
    assert figures["p95_abs_error_mm"]["median"] == np.median(p95)
    assert figures["p95_abs_error_mm"]["p90"] == np.quantile(p95, 0.9, method="inverted_cdf")
    assert figures["p95_abs_error_mm"]["worst"] == p95.max()
    assert figures["time_within_tolerance_fraction"]["worst"] == 1 - p95.max() / 4
    assert figures["settled_fraction"] == np.mean(p95 <= 1.5)
    assert figures["settle_time_s"]["worst"] is None  # never settled
    assert figures["settle_time_s"]["median"] == np.median(np.where(p95 > 1.5, np.inf, p95))


def test_hand_computed_figures_and_an_infinite_median():
    """p95 0.2..2.0 mm in 0.2 steps: median 1.1, p90 (a trial's own value) 1.8, 5 of 10 <= 1."""
    rows = [row(k, p95=0.2 * (k + 1)) for k in range(10)]
    figures = summarize_population(rows, ["c"], 0.001)["per_controller"]["c"]
    assert figures["p95_abs_error_mm"]["median"] == pytest.approx(1.1)
    assert figures["p95_abs_error_mm"]["p90"] == pytest.approx(1.8)
    assert figures["p95_within_tolerance_fraction"] == 0.5
    assert figures["patients"] == 10
    # Two runs, one failed: the median lies between a number and infinity, so it is infinite.
    halves = summarize_population([row(0, p95=0.4), failed(1)], ["c"], 0.001)
    assert halves["per_controller"]["c"]["p95_abs_error_mm"]["median"] is None
    assert "failed" in summary_table(halves)


def test_a_failed_run_counts_as_the_worst_trial_not_as_no_trial():
    rows = [row(0), row(1), failed(2)]
    figures = summarize_population(rows, ["c"], 0.001)["per_controller"]["c"]
    assert figures["failed"] == 1
    assert figures["p95_within_tolerance_fraction"] == pytest.approx(2 / 3)
    assert figures["p95_abs_error_mm"]["worst"] is None  # infinite
    assert figures["time_within_tolerance_fraction"]["worst"] == 0.0
    assert figures["settled_fraction"] == pytest.approx(2 / 3)
    assert figures["overshoot_mm"]["worst"] == pytest.approx(0.1)  # over the runs that ran
    assert "failed" in summary_table(summarize_population(rows, ["c"], 0.001))


def test_reachable_only_figures_leave_out_the_unreachable_targets():
    rows = [row(0, p95=0.3), row(1, p95=5.0, reachable=False)]
    figures = summarize_population(rows, ["c"], 0.001)["per_controller"]["c"]
    assert figures["unreachable_targets"] == 1
    assert figures["p95_within_tolerance_fraction"] == 0.5
    assert figures["reachable_targets_only"]["runs"] == 1
    assert figures["reachable_targets_only"]["p95_within_tolerance_fraction"] == 1.0


def test_each_controller_is_summarised_on_its_own_rows():
    rows = [row(0, "a", p95=0.1), row(0, "b", p95=3.0)]
    per = summarize_population(rows, ["a", "b"], 0.001)["per_controller"]
    assert list(per) == ["a", "b"]
    assert per["a"]["p95_abs_error_mm"]["worst"] == 0.1
    assert per["b"]["p95_abs_error_mm"]["worst"] == 3.0
    table = summary_table(summarize_population(rows, ["a", "b"], 0.001))
    assert "0.10 / 0.10 / 0.10" in table and "3.00 / 3.00 / 3.00" in table


def test_the_supervisors_share_of_runs_counts_the_runs_that_ran():
    rows = [row(k) for k in range(4)] + [failed(4)]
    for r, latched, held in zip(
        rows[:4], ["", "pressure_jump", "no_camera", ""], [0, 0, 1, 0], strict=True
    ):
        r.update(safety_latched=latched, safety_held_air=bool(held))
    figures = summarize_population(rows, ["c"], 0.001)["per_controller"]["c"]
    assert figures["safety_latched_fraction"] == 0.5
    assert figures["safety_held_air_fraction"] == 0.25
    assert "50.0 % / 25.0 %" in summary_table(summarize_population(rows, ["c"], 0.001))
