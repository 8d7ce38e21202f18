"""The estimator's checks: each against its definition, in the filter, the fusion and the loop."""

import dataclasses

import numpy as np
import pytest
from scipy import stats

from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from maskless.systems.config_loading import asset_path
from maskless.systems.sensing.fault_detection import (
    frames_in,
    nis_bound,
    validate_fault_detection,
)
from maskless.systems.sensing.local_kalman_filter import (
    LocalFilterConfig,
    make_local_kalman_filter,
    predict,
)
from maskless.systems.sensing.track_fusion import fuse_tracks, make_track_fusion

DETECTION = load_scenario().fault_detection
PERIOD_S = 1 / 15
SIGMA_A2, SIGMA_R2 = 2000e-6, 70e-6
CAMERA_M, START_M = 1.0, 0.2
CONFIG = LocalFilterConfig(initial_position_std_m=0.01, initial_velocity_std_m_s=0.02)


@pytest.mark.parametrize("probability", [0.9, 0.99, 0.9999])
def test_the_nis_bound_is_the_chi_square_quantile_of_one_degree_of_freedom(probability):
    assert nis_bound(probability) == pytest.approx(stats.chi2.ppf(probability, 1), rel=1e-9)


def test_frames_in_a_duration_round_up_and_are_at_least_one():
    assert frames_in(1.0, 15.0) == 15 and frames_in(0.33, 15.0) == 5 and frames_in(0.0, 15) == 1


@pytest.mark.parametrize(
    "field, value", [("innovation_gate_probability", 1.0), ("stale_after_s", 0.0)]
)
def test_a_check_out_of_range_is_refused_naming_it(field, value):
    with pytest.raises(ConfigError, match=f"fault_detection.{field} = {value}"):
        validate_fault_detection(dataclasses.replace(DETECTION, **{field: value}))


@pytest.fixture(scope="module")
def kf():
    return make_local_kalman_filter(
        "kf",
        camera_height_m=CAMERA_M,
        frame_period_s=PERIOD_S,
        acceleration_variance_m2_s4=SIGMA_A2,
        measurement_variance_m2=SIGMA_R2,
        initial_height_m=START_M,
        valid_range_m=(0.4, 4.0),
        config=CONFIG,
        detection=DETECTION,
    )


def filter_context(
    kf, now_s, distance, valid=1.0, last_usable_s=0.0, rejected=0, repeated=0, last_distance=0.0
):
    """The filter at its start estimate, last ticked at 0, with the checks' memory given."""
    context = kf.CreateDefaultContext()
    state = np.zeros(10)
    state[6:] = [last_usable_s, rejected, repeated, last_distance]
    context.SetDiscreteState(state)
    context.SetTime(now_s)
    kf.GetInputPort("distance_m").FixValue(context, [distance])
    kf.GetInputPort("valid").FixValue(context, [valid])
    return context


def health(kf, context) -> dict:
    flags = kf.GetOutputPort("health").Eval(context)
    return dict(zip(("stale", "rejecting", "stuck"), flags > 0.5, strict=True))


def test_a_frame_outside_the_innovation_gate_is_not_used_and_counted(kf):
    """The gate is |z - ẑ| <= sqrt(bound S), S = P(k|k-1)[0, 0] + σ_r², from Eq. 8 here."""
    P0 = np.diag([CONFIG.initial_position_std_m**2, CONFIG.initial_velocity_std_m_s**2])
    _, P_prior = predict(np.array([START_M, 0.0]), P0, PERIOD_S, SIGMA_A2)
    half_width = np.sqrt(
        nis_bound(DETECTION.innovation_gate_probability) * (P_prior[0, 0] + SIGMA_R2)
    )
    for offset, used in ((0.99 * half_width, True), (1.01 * half_width, False)):
        context = filter_context(kf, PERIOD_S, CAMERA_M - START_M - offset)
        state = kf.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
        assert (state[0] != 0.0) == used  # the height moved only if the frame was used
        assert state[7] == (0 if used else 1)  # rejected frames in a row
        assert state[6] == (PERIOD_S if used else 0.0)  # the last usable frame's time


def test_stale_rejecting_and_stuck_flags_set_at_their_stated_bounds(kf):
    distance = CAMERA_M - START_M
    stale = DETECTION.stale_after_s
    assert not health(kf, filter_context(kf, 0.99 * stale, distance))["stale"]
    assert health(kf, filter_context(kf, 1.01 * stale, distance))["stale"]
    reject_frames = frames_in(DETECTION.rejecting_after_s, 15.0)
    assert not health(kf, filter_context(kf, 0.1, distance, rejected=reject_frames - 1))[
        "rejecting"
    ]
    assert health(kf, filter_context(kf, 0.1, distance, rejected=reject_frames))["rejecting"]
    stuck_frames = frames_in(DETECTION.stuck_after_s, 15.0)
    assert not health(kf, filter_context(kf, 0.1, distance, repeated=stuck_frames - 1))["stuck"]
    assert health(kf, filter_context(kf, 0.1, distance, repeated=stuck_frames))["stuck"]


def test_identical_readings_are_counted_and_any_change_resets_the_count(kf):
    same = filter_context(kf, PERIOD_S, 0.8, repeated=3, last_distance=0.8)
    assert kf.EvalUniquePeriodicDiscreteUpdate(same).get_vector().CopyToVector()[8] == 4
    changed = filter_context(kf, PERIOD_S, 0.8001, repeated=3, last_distance=0.8)
    assert kf.EvalUniquePeriodicDiscreteUpdate(changed).get_vector().CopyToVector()[8] == 0


def fused(tracks, healthy):
    fusion = make_track_fusion(["a", "b"], DETECTION)
    context = fusion.CreateDefaultContext()
    for name, (x, P), ok in zip(["a", "b"], tracks, healthy, strict=True):
        fusion.GetInputPort(f"{name}_estimated_state").FixValue(context, x)
        fusion.GetInputPort(f"{name}_covariance").FixValue(context, P.ravel())
        fusion.GetInputPort(f"{name}_health").FixValue(context, [0.0, 0.0, 0.0 if ok else 1.0])
    return [
        fusion.GetOutputPort(p).Eval(context) for p in ("estimated_state", "covariance", "health")
    ]


P_TRACK = np.array([[1e-5, 2e-6], [2e-6, 4e-5]])


def test_a_flagged_track_is_left_out_and_the_other_carries_on():
    tracks = [(np.array([0.200, 0.0]), P_TRACK), (np.array([0.210, 0.0]), 2 * P_TRACK)]
    x, P, health_out = fused(tracks, [True, True])
    x_ref, P_ref = fuse_tracks([t[0] for t in tracks], [t[1] for t in tracks])
    np.testing.assert_allclose(x, x_ref, rtol=1e-12, atol=1e-15)  # both healthy: Eq. 10
    assert health_out[0] == 2
    x, P, health_out = fused(tracks, [False, True])
    np.testing.assert_allclose(x, tracks[1][0], atol=1e-12)
    np.testing.assert_allclose(P.reshape(2, 2), tracks[1][1], rtol=1e-6)
    assert health_out[0] == 1
    _, P, health_out = fused(tracks, [False, False])
    assert health_out[0] == 0 and health_out[2] == 1  # nothing trusted: uncertain


def test_two_healthy_tracks_disagree_beyond_their_stated_sigmas():
    gap_std = np.sqrt(2 * P_TRACK[0, 0])
    for sigmas, flagged in ((0.99, False), (1.01, True)):
        gap = sigmas * DETECTION.disagreement_sigmas * gap_std
        tracks = [(np.array([0.2, 0.0]), P_TRACK), (np.array([0.2 + gap, 0.0]), P_TRACK)]
        assert fused(tracks, [True, True])[2][1] == flagged
        assert fused(tracks, [True, False])[2][1] == 0  # a left-out track is not compared


def test_an_uncertain_fused_estimate_is_flagged_beyond_its_stated_std():
    for factor, flagged in ((0.99, False), (1.01, True)):
        variance = 2 * (factor * DETECTION.max_fused_std_m) ** 2  # two equal tracks halve it
        P = np.diag([variance, 1e-4])
        tracks = [(np.array([0.2, 0.0]), P), (np.array([0.2, 0.0]), P)]
        assert fused(tracks, [True, True])[2][2] == flagged


@pytest.mark.parametrize(
    "example, within_s",
    [
        ("both-cameras-lost.yaml", 0.5),
        ("camera-biased.yaml", 1.0),
        ("camera-frozen.yaml", 1.0 + PERIOD_S),
        ("camera-non-finite.yaml", 0.5),
        ("dropout-burst.yaml", 2.0),
    ],
)
def test_each_shipped_camera_fault_is_detected_within_its_bound(example, within_s):
    run = simulate(load_scenario(asset_path(f"faults/{example}"), duration_s=40.0))
    for fault in run.metrics["fault_detection"]["faults"].values():
        assert fault["detected_by"] is not None
        assert fault["latency_s"] <= within_s


def test_a_frozen_camera_is_left_out_and_the_other_keeps_the_head_within_1_mm():
    run = simulate(load_scenario(asset_path("faults/camera-frozen.yaml")))
    tracking = run.metrics["tracking"]
    assert tracking["p95_abs_error_mm"] <= 1.0
    assert run.metrics["fault_detection"]["fusion"]["fewest_tracks_used"] == 1


@pytest.mark.parametrize("presets", [[], ["paper_camera_noise"]])
def test_no_check_fires_on_a_healthy_run(presets):
    """Patient motion on; past the filters' start (the initial guess is uncertain by design)."""
    for seed in range(2):
        scenario = load_scenario(presets=presets, random_seed=seed)
        scenario.patient_motion.enabled = True
        s = simulate(scenario).signals
        for name in ("kinect_v1_filter.health", "kinect_v2_filter.health", "fusion.health"):
            late = s[name].times_s >= scenario.metrics.estimation_start_s
            flags = s[name].values[:, late]
            if name == "fusion.health":
                assert np.all(flags[0] == 2)
                flags = flags[1:]
            assert not np.any(flags > 0.5), name
