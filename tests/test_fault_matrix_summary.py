"""The fault matrix's figures and targets against hand-made rows."""

import pytest

from maskless.analysis.fault_matrix_summary import CaseFaults, case_figures, summarize_fault_matrix

CASES = {
    "nominal": CaseFaults(),
    "one-frozen": CaseFaults((("camera_frozen", "kinect_v1"),)),
    "both-lost": CaseFaults((("camera_dead", "kinect_v1"), ("camera_dead", "kinect_v2"))),
    "stuck": CaseFaults((("inlet_stuck", ""),)),
}


def row(case, seed, **figures):
    base = {
        "case": case,
        "seed": seed,
        "error": "",
        "detection_latency_s": None,
        "safe_state_latency_s": None,
        "safe_state_reason": None,
        "worst_excursion_mm": None,
        "p95_abs_error_mm": 0.2,
        "beam_on_while_off_target_fraction": 0.0,
        "beam_held_while_on_target_fraction": 0.1,
        "valve_currents_out_of_range": 0,
        "max_gauge_pressure_kpa": 3.0,
    }
    base.update(figures)
    return base


def passing_rows():
    return [
        row("nominal", 0),
        row("one-frozen", 0, detection_latency_s=0.9, p95_abs_error_mm=0.3),
        row("one-frozen", 1, detection_latency_s=0.7, p95_abs_error_mm=0.5),
        row(
            "both-lost",
            0,
            detection_latency_s=0.4,
            safe_state_latency_s=0.45,
            safe_state_reason="no_camera",
            worst_excursion_mm=1.5,
        ),
        row("stuck", 0, beam_on_while_off_target_fraction=0.0009, worst_excursion_mm=4.0),
    ]


def summarize(rows):
    return summarize_fault_matrix(rows, CASES, camera_count=2, pressure_limit_kpa=15.0)


def test_the_kinds_of_case():
    assert CASES["nominal"].nominal and not CASES["stuck"].nominal
    assert CASES["one-frozen"].one_camera and not CASES["both-lost"].one_camera
    assert CASES["both-lost"].cameras_lost(2) and not CASES["one-frozen"].cameras_lost(2)
    assert not CaseFaults((("camera_bias", "a"), ("camera_bias", "b"))).one_camera


def test_a_case_reports_median_and_worst():
    figures = case_figures(passing_rows()[1:3])
    assert figures["runs"] == 2 and figures["detected"] == 2
    assert figures["detection_latency_s"] == {"median": pytest.approx(0.8), "worst": 0.9}
    assert figures["p95_abs_error_mm"]["worst"] == 0.5


def test_every_target_met_when_the_rows_are_within_their_bounds():
    summary = summarize(passing_rows())
    assert summary["all_targets_met"], [t for t in summary["targets"] if not t["met"]]
    assert summary["seeds"] == 2 and summary["runs"] == 5


@pytest.mark.parametrize(
    "change, missed",
    [
        ((0, {"beam_on_while_off_target_fraction": 1e-9}), "nominal"),
        ((4, {"beam_on_while_off_target_fraction": 0.0011}), "any fault"),
        ((1, {"detection_latency_s": 1.01}), "detection"),
        ((1, {"detection_latency_s": None}), "detection"),  # a frozen camera never caught
        ((2, {"p95_abs_error_mm": 1.6}), "p95"),
        ((3, {"safe_state_latency_s": 0.55}), "safe state"),
        ((3, {"worst_excursion_mm": 2.1}), "excursion"),
        ((4, {"valve_currents_out_of_range": 1}), "valve currents"),
        ((4, {"max_gauge_pressure_kpa": 15.1}), "pressure"),
        ((4, {"error": "RuntimeError: boom"}), "raised"),
    ],
)
def test_each_target_is_missed_past_its_bound(change, missed):
    rows = passing_rows()
    index, figures = change
    rows[index].update(figures)
    summary = summarize(rows)
    failed = [t["target"] for t in summary["targets"] if not t["met"]]
    assert not summary["all_targets_met"]
    assert any(missed in text for text in failed), failed
