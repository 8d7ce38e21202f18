import pytest

from maskless.analysis.summary import format_summary, summarize
from maskless.diagrams.simulate import run_closed_loop


def test_the_paper_plant_does_not_follow_the_reference(short_run):
    summary = summarize(short_run)
    tracking, model = summary["tracking"], summary["paper_model"]
    # Its own DC gain bounds the head's travel: the whole valve range moves it < 0.04 mm.
    assert max(abs(v) for v in model["steady_lift_range_mm"]) < 0.04
    assert tracking["head_travel_mm"] < 0.04
    assert not tracking["settled"]
    assert tracking["final_error_mm"] == pytest.approx(-5.0, abs=0.05)


def test_fusion_beats_each_local_track(short_run):
    estimation = summarize(short_run)["estimation"]
    assert estimation["fused_error_std_mm"] < estimation["kinect_v1_error_std_mm"]
    assert estimation["fused_error_std_mm"] < estimation["kinect_v2_error_std_mm"]
    # The paper's reported bound (Sec. III-C).
    assert estimation["fused_error_std_mm"] < short_run.config.paper.reported_fused_std_mm


def test_a_camera_that_never_sees_the_face_reports_no_error(config):
    config.duration_s = 6.0
    config.kinect_v1.mount_height_m = 0.3  # the face is out of the camera's range
    summary = summarize(run_closed_loop(config))
    assert summary["estimation"]["kinect_v1_valid_fraction"] == 0.0
    assert summary["estimation"]["kinect_v1_error_std_mm"] is None
    assert "kinect_v1  no valid frames" in format_summary(summary)


def test_text_names_the_configured_valve_range(config):
    config.duration_s = 3.0
    config.paper.valve_saturation_current_ma = 150.0
    text = format_summary(summarize(run_closed_loop(config)))
    assert "(0-150 mA)" in text
    assert "overshoot n/a (no reference step)" in text  # the default step at 10 s never came
