"""The safety figures against hand-counted times on a made-up log."""

import numpy as np
import pytest

from maskless.analysis.safety_figures import SafetyLog, safety_figures, time_to_safe_state_s
from maskless.systems.control.safety_supervisor import REASONS

TOLERANCE_M = 0.001


def made_up_log():
    """Ten ticks of 0.1 s: the head leaves the band at tick 4, a camera is excluded at tick 6."""
    times = np.arange(10) * 0.1
    reference = np.full(10, 0.2)
    head = reference + np.array([0, 0, 0, 0, 2, 2, 2, 0, 0, 0]) * 1e-3
    beam_hold = np.array([1, 1, 0, 0, 0, 1, 1, 1, 1, 1], float)
    reasons = np.zeros((len(REASONS), 10))
    reasons[REASONS.index("camera_excluded"), 6:] = 1
    return SafetyLog(
        times_s=times,
        head_height_m=head,
        reference_m=reference,
        beam_hold=beam_hold,
        reasons=reasons,
        mode=np.zeros(10),
        inlet_a=np.full(10, 0.1),
        outlet_a=np.zeros(10),
        gauge_pressure_pa=np.linspace(3000, 3900, 10),
    )


def test_beam_times_are_counted_per_tick_against_the_truth():
    f = safety_figures(made_up_log(), TOLERANCE_M)
    assert f["beam_on_s"] == pytest.approx(0.3)  # ticks 2, 3, 4
    assert f["beam_hold_s"] == pytest.approx(0.7)
    assert f["beam_hold_fraction"] == pytest.approx(0.7)
    assert f["beam_on_while_off_target_s"] == pytest.approx(0.1)  # tick 4
    assert f["beam_held_while_on_target_s"] == pytest.approx(0.5)  # ticks 0, 1, 7, 8, 9
    assert f["state_at_end"] == "degraded"
    assert f["latched_at_end"] == ["camera_excluded"]
    assert f["events"] == [
        {"reason": "camera_excluded", "first_s": pytest.approx(0.6), "action": "continue"}
    ]
    assert f["max_gauge_pressure_kpa"] == pytest.approx(3.9)
    assert f["non_finite_valve_currents"] == 0
    assert f["valve_current_range_ma"] == [0.0, pytest.approx(100.0)]


def test_the_safe_state_is_the_first_reason_latched_after_the_fault():
    assert time_to_safe_state_s(made_up_log(), 0.35) == ("camera_excluded", pytest.approx(0.25))
    # Latched at 0.6 s and still latched: no answer to a fault at 0.75 s...
    assert time_to_safe_state_s(made_up_log(), 0.75) == (None, None)
    # ...but a reason that latches after it is.
    log = made_up_log()
    log.reasons[REASONS.index("pressure_jump"), 8:] = 1
    assert time_to_safe_state_s(log, 0.75) == ("pressure_jump", pytest.approx(0.05))
