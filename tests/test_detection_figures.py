"""When flags were first set, for how long, and the latency after a fault."""

import numpy as np

from maskless.analysis.detection_figures import (
    detection_latency_s,
    first_set_s,
    flag_figures,
    rises,
    set_fraction,
)

TIMES = np.arange(10) * 0.5  # 0 .. 4.5 s
A = np.array([0, 1, 0, 0, 0, 0, 1, 1, 1, 1], dtype=float)
B = np.array([0, 0, 0, 0, 0, 1, 1, 0, 0, 0], dtype=float)


def test_first_set_from_a_time_and_the_fraction_set():
    assert first_set_s(TIMES, A) == 0.5
    assert first_set_s(TIMES, A, from_s=1.0) == 3.0
    assert first_set_s(TIMES, np.zeros(10)) is None
    assert set_fraction(A) == 0.5
    assert flag_figures(TIMES, {"a": A}) == {"a": {"first_set_s": 0.5, "set_fraction": 0.5}}


def test_the_latency_is_the_earliest_flag_after_the_fault_starts():
    assert detection_latency_s(TIMES, {"a": A, "b": B}, start_s=1.0) == ("b", 1.5)
    assert detection_latency_s(TIMES, {"b": B}, start_s=3.5) == (None, None)


def test_a_latched_flag_fires_where_it_rises():
    flag = np.array([0, 1, 1, 0, 0, 1, 1, 1])
    np.testing.assert_array_equal(rises(flag), [0, 1, 0, 0, 0, 1, 0, 0])
    np.testing.assert_array_equal(rises(np.ones(3)), [1, 0, 0])
