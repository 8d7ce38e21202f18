"""A run's logs as recording channels, checked on hand-made logs.

Every exported port lands in its topic under its own name, stamped in whole nanoseconds.
"""

import numpy as np
import pytest

from maskless.diagrams.closed_loop import Signal
from maskless.diagrams.run_recording import signal_channels

TIMES_S = np.array([0.0, 1.0 / 15.0, 2.0 / 15.0])


def logs(camera_names):
    row = np.array([[0.20, 0.21, 0.22]])
    state = np.vstack([row[0], [0.0, 0.15, 0.15]])
    covariance = np.tile(np.array([[1e-6], [2e-7], [2e-7], [3e-6]]), 3)
    s = {
        "reference_head_height_m": Signal(TIMES_S, row + 0.005),
        "head_height_m": Signal(TIMES_S, row),
        "inlet_valve_current_a": Signal(TIMES_S, np.array([[0.10, 0.12, 0.14]])),
        "outlet_valve_current_a": Signal(TIMES_S, np.zeros((1, 3))),
        "fusion.estimated_state": Signal(TIMES_S, state),
        "fusion.covariance": Signal(TIMES_S, covariance),
    }
    for name in camera_names:
        s[f"{name}.distance_m"] = Signal(TIMES_S, 0.9 - row)
        s[f"{name}.valid"] = Signal(TIMES_S, np.array([[0.0, 1.0, 1.0]]))
        s[f"{name}_filter.estimated_state"] = Signal(TIMES_S, state)
        s[f"{name}_filter.covariance"] = Signal(TIMES_S, covariance)
    return s


def test_each_port_lands_in_its_topic_under_its_own_name():
    channels = {c.topic: c for c in signal_channels(logs(["a", "b"]), ["a", "b"])}
    assert set(channels) == {
        "/reference",
        "/plant/head_height",
        "/sensors/a/measurement",
        "/sensors/b/measurement",
        "/filters/a/estimate",
        "/filters/b/estimate",
        "/fusion/estimate",
        "/controller/command",
    }
    assert set(channels["/controller/command"].columns) == {
        "inlet_valve_current_a",
        "outlet_valve_current_a",
    }
    head = channels["/plant/head_height"].columns["head_height_m"]
    np.testing.assert_array_equal(head, [0.2, 0.21, 0.22])
    fused = channels["/fusion/estimate"].columns
    np.testing.assert_array_equal(fused["head_velocity_m_s"], [0.0, 0.15, 0.15])
    # The covariance port's four logged entries become the 2x2 matrix of each message.
    np.testing.assert_array_equal(fused["covariance"][0], [[1e-6, 2e-7], [2e-7, 3e-6]])
    valid = channels["/sensors/a/measurement"].columns["valid"]
    np.testing.assert_array_equal(valid, [False, True, True])


def test_stamps_are_whole_nanoseconds_rounded_not_truncated():
    (reference, *_) = signal_channels(logs([]), [])
    # 1/15 s is 66666666.67 ns: rounding gives ...67, truncation would give ...66.
    assert reference.times_ns.tolist() == [0, 66_666_667, 133_333_333]


def test_a_missing_camera_log_is_named():
    with pytest.raises(KeyError, match="c.distance_m"):
        signal_channels(logs(["a"]), ["a", "c"])
