"""Where each hold settled, read from the hold: against first-order closed forms.

A first-order lag y[k+1] = p y[k] + (1 - p) L approaches a held level L as L + (y0 - L) p^k, so
it is within 2 % of its step from k = log(0.02) / log(p) on: the reference for where a hold
settles. Noise is white and its window average's deviation sigma / sqrt(window).
"""

import numpy as np
import pytest

from maskless.analysis.identification.hammerstein import (
    _capped_by_holds,
    _settle_samples,
)
from maskless.analysis.identification.hold_settling import (
    TIMING_WINDOW_S,
    settled_levels_by_holds,
    settling_from_holds,
    window_averages,
    window_noise,
)
from maskless.analysis.identification.settled_curve import settled_levels


def _first_order(levels, poles):
    """The lag's output; ``poles`` (N,) the pole in force at each sample."""
    y = np.zeros(levels.size)
    for k in range(1, levels.size):
        y[k] = poles[k - 1] * y[k - 1] + (1.0 - poles[k - 1]) * levels[k - 1]
    return y


def test_a_hold_settles_where_its_output_stays_within_two_percent_of_its_step():
    levels = np.repeat([0.0, 5.0], [100, 400])
    y = _first_order(levels, np.full(levels.size, 0.95))
    # A fixed time of 64 samples, shorter than the lag's, and a window of 2 samples.
    found = settled_levels_by_holds(levels[:, None], y, 64, 20)
    # The hold begins at sample 100, and y[100 + j] = 5 (1 - 0.95^j): within 2 % from j = k on.
    k = int(np.ceil(np.log(0.02) / np.log(0.95)))
    settled_after = 400 - found.samples[-1]
    assert k <= settled_after <= k + 2  # a window's lag at most
    assert found.outputs[-1] == pytest.approx(5.0, abs=0.02 * 5.0)


def test_a_hold_never_settles_before_the_fixed_time():
    levels = np.repeat([0.0, 5.0], [100, 400])
    y = _first_order(levels, np.full(levels.size, 0.95))
    found = settled_levels_by_holds(levels[:, None], y, 200, 20)  # past the lag's 77 samples
    fixed = settled_levels(levels[:, None], y, 200, 20)
    np.testing.assert_array_equal(found.samples, fixed.samples)
    np.testing.assert_array_equal(found.outputs, fixed.outputs)


def test_a_hold_still_rising_at_its_end_is_left_out_where_the_fixed_time_keeps_it():
    # Pole 0.995: 2 % only after 781 samples, and the hold lasts 300.
    levels = np.repeat([0.0, 5.0, 5.0], [200, 300, 1])
    levels[-1] = 0.0
    y = _first_order(levels, np.full(levels.size, 0.995))
    fixed = settled_levels(levels[:, None], y, 100, 20)
    assert 5.0 in fixed.currents[:, 0]
    assert fixed.outputs[list(fixed.currents[:, 0]).index(5.0)] < 0.8 * 5.0  # far from 5
    by_holds = settled_levels_by_holds(levels[:, None], y, 100, 20)
    assert 5.0 not in by_holds.currents[:, 0]


def test_fast_and_slow_approaches_each_settle_at_their_own_time():
    # Small steps approach fast (pole 0.8), the big one slowly (0.98): the fixed time that suits
    # the small ones averages the big one's approach.
    levels = np.repeat([0.0, 0.5, 0.2, 8.0, 8.3, 8.1], [150, 150, 150, 600, 150, 150])
    poles = np.full(levels.size, 0.8)
    poles[450:1050] = 0.98
    y = _first_order(levels, poles)
    by_holds = settled_levels_by_holds(levels[:, None], y, 64, 20)
    held = levels[[0, 150, 300, 450, 1050, 1200]]
    np.testing.assert_array_equal(by_holds.currents[:, 0], held)
    steps = np.abs(np.diff(held[1:], prepend=0.0))
    assert np.all(np.abs(by_holds.outputs[1:] - held[1:]) <= 0.02 * steps)
    fixed = settled_levels(levels[:, None], y, 64, 20)
    np.testing.assert_array_equal(fixed.currents[:, 0], held)
    assert abs(fixed.outputs[3] - 8.0) > 0.02 * 7.8  # the big step: past its own 2 %
    # The small holds settled within the fixed time, so it stands for them.
    small = [0, 1, 2, 4, 5]
    np.testing.assert_array_equal(by_holds.samples[small], fixed.samples[small])
    assert by_holds.samples[3] < fixed.samples[3]


def test_the_records_first_hold_settles_from_where_it_began():
    # The record opens 6 above the level it holds, still falling, as a record cut from a longer
    # run does: its step is read from its own first window.
    levels = np.full(400, 1.0)
    y = 1.0 + 6.0 * 0.95 ** np.arange(400.0)
    found = settled_levels_by_holds(levels[:, None], y, 64, 20)
    k = int(np.ceil(np.log(0.02) / np.log(0.95)))  # within 2 % of the 6 from there on
    assert found.currents[:, 0].tolist() == [1.0]
    assert 400 - found.samples[0] >= k
    assert found.outputs[0] == pytest.approx(1.0, abs=0.02 * 6.0)


def test_the_noise_of_a_windows_average_is_read_from_the_record():
    rng = np.random.default_rng(3)
    sigma, window = 0.4, 16
    levels = np.repeat(rng.uniform(0.0, 10.0, 40), 500)
    y = _first_order(levels, np.full(levels.size, 0.9)) + sigma * rng.standard_normal(levels.size)
    noise = window_noise(window_averages(y, window), window)
    assert noise == pytest.approx(sigma / np.sqrt(window), rel=0.1)


def test_noisy_levels_are_within_their_noise_of_the_held_levels():
    rng = np.random.default_rng(4)
    levels = np.repeat(rng.uniform(0.0, 10.0, 30), 400)
    y = _first_order(levels, np.full(levels.size, 0.95)) + 0.3 * rng.standard_normal(levels.size)
    found = settled_levels_by_holds(levels[:, None], y, 320, 40)
    assert found.outputs.size >= 28
    # Each mean's error: its noise (0.3 / sqrt(samples)) four times over, and 2 % of a step.
    tolerance = 4 * 0.3 / np.sqrt(found.samples) + 0.2
    assert np.all(np.abs(found.outputs - found.currents[:, 0]) < tolerance)


def test_a_record_of_one_hold_or_too_short_holds_gives_no_levels():
    levels = np.repeat([1.0, 2.0, 3.0], [5, 5, 5])
    y = _first_order(levels, np.full(levels.size, 0.5))
    found = settled_levels_by_holds(levels[:, None], y, 64, 20)
    assert found.outputs.size == 0
    assert found.currents.shape == (0, 1)


def _stepped_record(hold_samples, pole, noise=0.01, seed=0):
    """(u (N, 1), y (N,)): a lag with pole ``pole`` through holds at 0, 5, 1, 4, 0, seeded noise."""
    levels = np.repeat([0.0, 5.0, 1.0, 4.0, 0.0], [200] + [hold_samples] * 4)
    rng = np.random.default_rng(seed)
    y = _first_order(levels, np.full(levels.size, pole)) + noise * rng.standard_normal(levels.size)
    return levels[:, None], y


@pytest.mark.parametrize("hold_samples", [450, 600, 1200])
def test_a_records_settling_time_is_timed_from_its_large_steps_approaches(hold_samples):
    u, y = _stepped_record(hold_samples, 0.99)
    # Within 2 % of each step from k = log(0.02) / log(0.99) = 389.3 samples on: its tail fitted
    # as the exponential it is, to within a window (10 samples), whether the hold ends soon
    # after (450: its last quarter's mean is then 2 % short of the level) or long after.
    k = np.log(0.02) / np.log(0.99)
    assert settling_from_holds(u, y, 10) == pytest.approx(k, abs=10)


def test_no_settling_time_where_the_holds_end_before_their_steps_settle_or_in_the_noise():
    # Pole 0.995: 2 % only after 781 samples, and every hold lasts 300.
    u, y = _stepped_record(300, 0.995)
    assert settling_from_holds(u, y, 10) is None
    # Steps of 5 whose 5 % (0.25) lies within five deviations of the noise's 10-sample average.
    u, y = _stepped_record(600, 0.99, noise=0.5)
    assert settling_from_holds(u, y, 10) is None


def test_the_hammerstein_settling_time_is_the_poles_unless_the_large_steps_settled_sooner():
    u, y = _stepped_record(600, 0.99)
    timed = settling_from_holds(u, y, 10)
    # Samples of 0.5 s: TIMING_WINDOW_S (5 s) is the 10 samples timed above. A pole settling
    # slower than the steps did (0.999: 4 time constants are 3,998 samples) gives way to them; a
    # faster one stands.
    assert TIMING_WINDOW_S / 0.5 == 10
    assert _settle_samples(_capped_by_holds(0.999, u, y, 0.5)) == timed
    assert _capped_by_holds(0.95, u, y, 0.5) == 0.95
