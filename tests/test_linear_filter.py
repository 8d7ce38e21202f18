"""filter_signal against scipy.signal.lfilter, the filter it stands in for."""

import numpy as np
import pytest
import scipy.signal

from maskless.analysis.identification.linear_filter import filter_signal


def _reference(numerator, denominator, signal, initial_state):
    if initial_state is None:
        return scipy.signal.lfilter(numerator, denominator, signal)
    return scipy.signal.lfilter(numerator, denominator, signal, zi=initial_state)[0]


@pytest.mark.parametrize("seed", range(40))
@pytest.mark.parametrize("with_state", [False, True])
def test_random_filters_match_lfilter(seed, with_state):
    rng = np.random.default_rng(seed)
    numerator = rng.standard_normal(rng.integers(1, 6))
    # Any leading coefficient, either sign: lfilter normalises by it, and so must this.
    lead = rng.uniform(0.5, 2.0) * rng.choice([-1.0, 1.0])
    denominator = np.concatenate([[lead], 0.3 * rng.standard_normal(rng.integers(0, 5))])
    signal = rng.standard_normal(rng.integers(1, 60))
    size = max(numerator.size, denominator.size) - 1
    state = rng.standard_normal(size) if with_state else None
    expected = _reference(numerator, denominator, signal, state)
    np.testing.assert_allclose(
        filter_signal(numerator, denominator, signal, state), expected, rtol=1e-11, atol=1e-12
    )


def test_a_long_resonant_filter_matches_lfilter():
    # Poles at 0.97 e^{±0.1j}: a slow, ringing recursion over 20,000 samples, as PEM runs.
    rng = np.random.default_rng(3)
    signal = rng.standard_normal(20_000)
    denominator = np.poly(0.97 * np.exp([0.1j, -0.1j])).real
    numerator = [0.0, 1.0, 0.5]
    expected = scipy.signal.lfilter(numerator, denominator, signal)
    got = filter_signal(numerator, denominator, signal)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-10 * np.max(np.abs(expected)))


def test_an_unstable_filter_grows_as_lfilter_does():
    signal = np.zeros(50)
    signal[0] = 1.0
    expected = scipy.signal.lfilter([1.0], [1.0, -1.5], signal)
    np.testing.assert_allclose(filter_signal([1.0], [1.0, -1.5], signal), expected, rtol=1e-12)


def test_filters_sharing_a_length_do_not_share_coefficients():
    # The band is cached per denominator: alternating two of one order must not mix them.
    signal = np.random.default_rng(4).standard_normal(300)
    first, second = [1.0, -0.5, 0.2], [1.0, 0.3, -0.1]
    for _ in range(3):
        for denominator in (first, second):
            np.testing.assert_allclose(
                filter_signal([1.0], denominator, signal),
                scipy.signal.lfilter([1.0], denominator, signal),
                rtol=1e-12,
                atol=1e-13,
            )


def test_the_caller_keeps_its_signal_and_an_empty_signal_gives_nothing():
    signal = np.arange(5.0)
    filter_signal([1.0], [1.0, -0.5], signal)
    np.testing.assert_array_equal(signal, np.arange(5.0))
    assert filter_signal([1.0, 2.0], [1.0, -0.5], np.zeros(0)).shape == (0,)


@pytest.mark.parametrize(
    ("arguments", "message"),
    [
        (([1.0], [0.0, 1.0], np.ones(3)), "leading coefficient"),
        (([1.0], [], np.ones(3)), "leading coefficient"),
        (([], [1.0], np.ones(3)), "numerator"),
        (([1.0], [1.0], np.ones((3, 2))), "1-D"),
        (([1.0, 0.5], [1.0, 0.2, 0.1], np.ones(3), [1.0]), "expected 2 values"),
    ],
)
def test_bad_arguments_are_named(arguments, message):
    with pytest.raises(ValueError, match=message):
        filter_signal(*arguments)
