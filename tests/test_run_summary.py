"""Run summaries: tracking and estimation, the paper's fused-error bound and the clinical bar."""

import pytest

from maskless.diagrams.run_summary import format_summary, summarize
from maskless.diagrams.simulation import simulate


def test_the_paper_plant_does_not_follow_the_reference(paper_short_run):
    summary = summarize(paper_short_run)
    tracking, model = summary["tracking"], summary["paper_model"]
    # Its own DC gain bounds the head's travel: the whole valve range moves it < 0.04 mm.
    assert max(abs(v) for v in model["steady_lift_range_mm"]) < 0.04
    assert tracking["head_travel_mm"] < 0.04
    assert not tracking["settled"]
    assert tracking["final_error_mm"] == pytest.approx(-5.0, abs=0.05)


@pytest.mark.parametrize("run_name", ["short_run", "paper_short_run"])
def test_fusion_beats_each_local_track(run_name, request):
    short_run = request.getfixturevalue(run_name)
    estimation = summarize(short_run)["estimation"]
    assert estimation["fused_error_std_mm"] < estimation["kinect_v1_error_std_mm"]
    assert estimation["fused_error_std_mm"] < estimation["kinect_v2_error_std_mm"]
    # The paper's reported bound (Sec. III-C).
    assert estimation["fused_error_std_mm"] < short_run.scenario.paper.reported_fused_std_mm


def test_a_camera_that_never_sees_the_face_reports_no_error(config):
    config.duration_s = 6.0
    config.cameras["kinect_v1"].mount_height_m = 0.3  # the face is out of the camera's range
    summary = summarize(simulate(config))
    assert summary["estimation"]["kinect_v1_valid_fraction"] == 0.0
    assert summary["estimation"]["kinect_v1_error_std_mm"] is None
    assert "kinect_v1  no valid frames" in format_summary(summary)


def test_text_names_the_configured_valve_range(paper_config):
    config = paper_config
    config.duration_s = 3.0
    config.paper.valve_saturation_current_ma = 150.0
    text = format_summary(summarize(simulate(config)))
    assert "(0-150 mA)" in text
    assert "overshoot n/a (no reference step)" in text  # the default step at 10 s never came


def test_offset_free_lqg_settles_the_default_step_within_the_clinical_bar(short_run):
    tracking = summarize(short_run)["tracking"]
    # Issue 5's targets: settle within 1 mm in <= 10 s of the 5 mm step, overshoot <= 1 mm.
    assert tracking["settled"]
    assert tracking["settle_time_s"] - 2.0 <= 10.0
    assert tracking["overshoot_mm"] <= 1.0
    assert tracking["p95_abs_error_mm"] <= 1.0
    assert tracking["window_s"] == [12.0, pytest.approx(20.0)]
    assert tracking["time_within_tolerance_fraction"] == 1.0
    assert tracking["head_travel_mm"] == pytest.approx(5.0, abs=1.0)
