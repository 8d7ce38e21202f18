"""Tracking and estimation metrics against closed-form first- and second-order step responses."""

import math

import numpy as np
import pytest

from maskless.analysis.metrics import estimate_error_std_m, tracking_metrics

TOL = 0.001


def test_first_order_step_settles_at_the_closed_form_time():
    tau, step, t_step = 2.0, 0.005, 1.0
    t = np.arange(0, 40, 0.001)
    reference = np.where(t >= t_step, step, 0.0)
    head = np.where(t >= t_step, step * (1 - np.exp(-(t - t_step) / tau)), 0.0)
    m = tracking_metrics(
        t,
        head,
        reference,
        last_step_time_s=t_step,
        tolerance_m=TOL,
        evaluation_delay_s=30,
    )
    # |e| = step exp(-t/tau) <= tol  <=>  t >= tau ln(step/tol)
    assert m.settled
    assert m.settle_time_s == pytest.approx(tau * math.log(step / TOL), abs=2e-3)
    assert m.overshoot_m == 0.0
    assert m.max_abs_error_m <= TOL


def test_underdamped_step_overshoot_is_the_closed_form_peak():
    zeta, wn, step = 0.3, 2.0, 0.004
    t = np.arange(0, 60, 0.001)
    wd = wn * math.sqrt(1 - zeta**2)
    phi = math.acos(zeta)
    response = 1 - np.exp(-zeta * wn * t) / math.sqrt(1 - zeta**2) * np.sin(wd * t + phi)
    m = tracking_metrics(
        np.concatenate([[-1.0], t]),
        np.concatenate([[0.0], step * response]),
        np.concatenate([[0.0], np.full(t.size, step)]),
        last_step_time_s=0.0,
        tolerance_m=TOL,
        evaluation_delay_s=30,
    )
    expected = step * math.exp(-zeta * math.pi / math.sqrt(1 - zeta**2))
    assert m.overshoot_m == pytest.approx(expected, rel=1e-4)


@pytest.mark.parametrize("end_s", [120.0, 30.0, 40.0])
def test_a_head_that_never_moves_is_unsettled_and_a_short_run_has_no_window(end_s):
    """40 s: the run ends on the window's first sample, which is no window either."""
    t = np.arange(0, end_s + 1e-9, 0.05)
    reference = np.where(t >= 10, 0.005, 0.0)
    m = tracking_metrics(
        t,
        np.zeros_like(t),
        reference,
        last_step_time_s=10.0,
        tolerance_m=TOL,
        evaluation_delay_s=30,
    )
    assert not m.settled and m.settle_time_s is None
    assert m.window_start_s == 40.0 and m.window_end_s == pytest.approx(t[-1])
    if end_s > 40.0:
        assert m.rms_error_m == pytest.approx(0.005)
        assert m.p95_abs_error_m == pytest.approx(0.005)
        assert m.time_within_tolerance_fraction == 0.0
    else:
        # The run ends before the window starts: no figures, rather than a one-sample window.
        assert m.p95_abs_error_m is None and m.time_within_tolerance_fraction is None


def test_estimate_error_std_ignores_bias():
    t = np.arange(1000) * 0.01
    rng = np.random.default_rng(0)
    noise = rng.normal(0, 0.002, t.size)
    assert estimate_error_std_m(t, 0.2 + 0.01 + noise, np.full(t.size, 0.2), 0.0) == pytest.approx(
        np.std(noise)
    )


def test_bad_lengths_raise():
    with pytest.raises(ValueError, match="equal length"):
        tracking_metrics(
            np.zeros(3),
            np.zeros(2),
            np.zeros(3),
            last_step_time_s=0,
            tolerance_m=TOL,
            evaluation_delay_s=1,
        )


def test_a_nan_head_is_never_settled():
    t = np.arange(0, 10, 0.1)
    head = np.where(t >= 5, np.nan, 0.0)
    m = tracking_metrics(
        t,
        head,
        np.zeros_like(t),
        last_step_time_s=0.0,
        tolerance_m=TOL,
        evaluation_delay_s=1.0,
    )
    assert not m.settled


def test_the_window_is_fixed_whether_or_not_the_head_settles():
    # A head that wanders outside the band late, then comes back: the window still starts 20 s
    # after the step (not where it last came back), so the excursion counts.
    t = np.arange(0, 60, 0.01)
    reference = np.where(t >= 10, 0.005, 0.0)
    head = reference.copy()
    excursion = (t >= 40) & (t < 45)  # 5 s of the 30 s window at 2 mm off
    head[excursion] += 0.002
    m = tracking_metrics(
        t, head, reference, last_step_time_s=10.0, tolerance_m=TOL, evaluation_delay_s=20.0
    )
    assert m.settled and m.settle_time_s == pytest.approx(35.0)
    assert m.window_start_s == 30.0 and m.window_end_s == pytest.approx(59.99)
    assert m.time_within_tolerance_fraction == pytest.approx(25 / 30, abs=1e-3)
    assert m.max_abs_error_m == pytest.approx(0.002)
    # p95 of a window 1/6 of whose samples are 2 mm off: 2 mm.
    assert m.p95_abs_error_m == pytest.approx(0.002)


def test_time_within_tolerance_of_a_sine_is_the_closed_form():
    # |a sin| <= tol for a fraction (2/pi) asin(tol/a) of the time.
    a = 0.002
    t = np.arange(0, 100, 0.001)
    head = a * np.sin(2 * np.pi * 0.25 * t)
    m = tracking_metrics(
        t, head, np.zeros_like(t), last_step_time_s=0.0, tolerance_m=TOL, evaluation_delay_s=0.0
    )
    expected = 2 / np.pi * np.arcsin(TOL / a)
    assert m.time_within_tolerance_fraction == pytest.approx(expected, abs=1e-3)
    assert m.rms_error_m == pytest.approx(a / np.sqrt(2), rel=1e-3)
