"""Excitation signals: uniform noise (Eq. 22-23), PRBS and multisines against their closed forms."""

import math

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from scipy import integrate, stats

from maskless.systems.control.excitation import (
    ExcitationSignal,
    add_excitation_source,
    clip_to_valve_range,
    clipped_fraction,
    excitation_signal,
    hold_samples,
    multilevel_prbs,
    multisine,
    prbs,
    theoretical_uniform_std,
    uniform_white_noise,
)

TS = 0.01  # s
OFFSET = 0.100  # A, a mid-range valve current
AMPLITUDE = 0.020  # A


# --- ExcitationSignal ---------------------------------------------------------------------------


def test_signal_arrays_are_read_only_copies():
    values = np.array([1.0, 2.0, 3.0])
    signal = ExcitationSignal(np.arange(3) * TS, values, TS, "test")
    values[0] = 10.0
    assert signal.values[0] == 1.0
    with pytest.raises(ValueError, match="read-only"):
        signal.values[0] = 5.0
    assert signal.num_samples == 3
    assert signal.duration_s == pytest.approx(3 * TS)


def test_single_sine_crest_factor_is_sqrt_two():
    # A cosine sampled over whole periods hits its peak and has RMS A / sqrt(2).
    n = 64
    values = OFFSET + AMPLITUDE * np.cos(2.0 * np.pi * 3 * np.arange(n) / n)
    signal = ExcitationSignal(np.arange(n) * TS, values, TS, "sine")
    assert signal.crest_factor() == pytest.approx(math.sqrt(2.0), rel=1e-12)
    assert signal.std() == pytest.approx(AMPLITUDE / math.sqrt(2.0), rel=1e-12)


def test_square_wave_crest_factor_is_one():
    values = np.tile([OFFSET + AMPLITUDE, OFFSET - AMPLITUDE], 10)
    signal = ExcitationSignal(np.arange(values.size) * TS, values, TS, "square")
    assert signal.crest_factor() == pytest.approx(1.0, rel=1e-12)


@pytest.mark.parametrize(
    "times_s, values, match",
    [
        (np.arange(3) * TS, np.zeros(4), "same length"),
        (np.array([0.0]), np.array([1.0]), "at least 2 samples"),
        (np.array([0.0, TS, 3 * TS]), np.zeros(3), "uniform step"),
        (np.array([TS, 2 * TS]), np.zeros(2), "start at 0"),
        (np.arange(2) * TS, np.array([0.0, np.nan]), "finite"),
        (np.zeros((2, 2)), np.zeros((2, 2)), "1-D"),
    ],
)
def test_signal_rejects_malformed_arrays(times_s, values, match):
    with pytest.raises(ValueError, match=match):
        ExcitationSignal(times_s, values, TS, "bad")


def test_crest_factor_of_constant_signal_raises():
    signal = ExcitationSignal(np.arange(4) * TS, np.full(4, OFFSET), TS, "constant")
    with pytest.raises(ValueError, match="constant"):
        signal.crest_factor()


# --- uniform white noise (Eq. 22-23) ------------------------------------------------------------


def test_theoretical_std_matches_integrated_variance_of_the_density():
    # Variance of the density 1 / (2A) on [-A, A], integrated numerically.
    variance, _ = integrate.quad(lambda x: x**2 / (2.0 * AMPLITUDE), -AMPLITUDE, AMPLITUDE)
    assert theoretical_uniform_std(AMPLITUDE) == pytest.approx(math.sqrt(variance), rel=1e-10)
    assert theoretical_uniform_std(3.0) == pytest.approx(math.sqrt(3.0))


def test_uniform_sample_moments_match_eq_23():
    n = 200_000
    signal = uniform_white_noise(AMPLITUDE, n * TS, TS, seed=1, offset=OFFSET)
    assert signal.num_samples == n
    assert signal.kind == "uniform"
    # Five standard errors: the sample mean has sd A / sqrt(3N); by the delta method the sample sd
    # has sd sqrt((mu4 - sigma^4) / N) / (2 sigma) = A / sqrt(15 N) (mu4 = A^4 / 5).
    assert abs(np.mean(signal.values) - OFFSET) < 5.0 * AMPLITUDE / math.sqrt(3.0 * n)
    assert abs(signal.std() - AMPLITUDE / math.sqrt(3.0)) < 5.0 * AMPLITUDE / math.sqrt(15.0 * n)
    # The crest factor of a uniform variable is A / (A / sqrt(3)) = sqrt(3).
    assert signal.crest_factor() == pytest.approx(math.sqrt(3.0), rel=0.01)


def test_uniform_support_and_distribution():
    n = 100_000
    signal = uniform_white_noise(AMPLITUDE, n * TS, TS, seed=2, offset=OFFSET)
    assert signal.values.min() >= OFFSET - AMPLITUDE
    assert signal.values.max() <= OFFSET + AMPLITUDE
    # Both edges are reached: P(no sample within 0.1 % of an edge) = (1 - 5e-4)^N ~ e^-50.
    margin = 1e-3 * AMPLITUDE
    assert signal.values.min() < OFFSET - AMPLITUDE + margin
    assert signal.values.max() > OFFSET + AMPLITUDE - margin
    reference = stats.uniform(loc=OFFSET - AMPLITUDE, scale=2.0 * AMPLITUDE)
    assert stats.kstest(signal.values, reference.cdf).pvalue > 1e-3


def test_uniform_times_start_at_zero_with_uniform_step():
    signal = uniform_white_noise(AMPLITUDE, 0.3, 0.1, seed=0)
    # 0.3 / 0.1 rounds to 2.9999999999999996 in floating point; still 3 samples.
    np.testing.assert_allclose(signal.times_s, [0.0, 0.1, 0.2])
    assert signal.sample_period_s == 0.1


# --- seeds --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "design, kwargs",
    [
        (uniform_white_noise, {}),
        (prbs, {}),
        (multisine, {"phases": "random"}),
        (multilevel_prbs, {"hold_s": (2 * TS, 9 * TS)}),
    ],
)
def test_same_seed_repeats_and_different_seed_differs(design, kwargs):
    first = design(AMPLITUDE, 500 * TS, TS, seed=7, offset=OFFSET, **kwargs)
    again = design(AMPLITUDE, 500 * TS, TS, seed=7, offset=OFFSET, **kwargs)
    other = design(AMPLITUDE, 500 * TS, TS, seed=8, offset=OFFSET, **kwargs)
    np.testing.assert_array_equal(first.values, again.values)
    assert not np.array_equal(first.values, other.values)


def test_schroeder_multisine_ignores_the_seed():
    first = multisine(AMPLITUDE, 500 * TS, TS, seed=1, frequency_band_hz=(0.5, 10.0))
    other = multisine(AMPLITUDE, 500 * TS, TS, seed=2, frequency_band_hz=(0.5, 10.0))
    np.testing.assert_array_equal(first.values, other.values)


# --- PRBS ---------------------------------------------------------------------------------------


@pytest.mark.parametrize("register_bits", [5, 7, 10])
@pytest.mark.parametrize("seed", [0, 3])
def test_prbs_full_period_is_a_maximum_length_sequence(register_bits, seed):
    n = 2**register_bits - 1
    signal = prbs(AMPLITUDE, n * TS, TS, seed=seed, offset=OFFSET)
    assert signal.kind == "prbs"
    levels = (signal.values - OFFSET) / AMPLITUDE
    np.testing.assert_allclose(np.abs(levels), 1.0, rtol=1e-12)
    bits = np.rint(levels).astype(int)
    # Balanced: 2^(n-1) ones and 2^(n-1) - 1 minus-ones.
    assert np.sum(bits == 1) == np.sum(bits == -1) + 1
    # Two-valued circular autocorrelation: N at lag 0, -1 at every other lag.
    autocorrelation = np.array([np.dot(bits, np.roll(bits, lag)) for lag in range(n)])
    assert autocorrelation[0] == n
    np.testing.assert_array_equal(autocorrelation[1:], -1)
    # About the mean A / N: peak A (1 + 1/N), RMS A sqrt(1 - 1/N^2).
    assert signal.crest_factor() == pytest.approx(math.sqrt((n + 1) / (n - 1)), rel=1e-12)


def test_prbs_values_are_only_the_two_levels_for_a_partial_period():
    signal = prbs(AMPLITUDE, 1000 * TS, TS, seed=4, offset=OFFSET)
    np.testing.assert_allclose(
        np.sort(np.unique(signal.values)), [OFFSET - AMPLITUDE, OFFSET + AMPLITUDE]
    )
    assert signal.crest_factor() == pytest.approx(1.0, abs=0.01)


def test_prbs_clock_periods_hold_each_bit():
    clock = 4
    held = prbs(AMPLITUDE, 1023 * clock * TS, TS, seed=5, offset=OFFSET, clock_periods=clock)
    plain = prbs(AMPLITUDE, 1023 * TS, TS, seed=5, offset=OFFSET)
    blocks = held.values.reshape(-1, clock)
    np.testing.assert_array_equal(blocks, blocks[:, :1].repeat(clock, axis=1))
    np.testing.assert_array_equal(blocks[:, 0], plain.values)


def test_prbs_clock_period_cuts_last_bit_short():
    signal = prbs(AMPLITUDE, 10 * TS, TS, seed=0, clock_periods=3)
    assert signal.num_samples == 10


@pytest.mark.parametrize("register_bits", [7, 10])
def test_prbs_half_period_shift_is_uncorrelated_with_the_plain_sequence(register_bits):
    # MLS closed form: b(t) = a(t + P // 2), so sum_t a(t) b(t - k) is a's circular
    # autocorrelation at lag P // 2 - k: P at k = P // 2 and -1 at every other lag.
    n = 2**register_bits - 1
    plain = prbs(AMPLITUDE, n * TS, TS, seed=6, offset=OFFSET)
    shifted = prbs(AMPLITUDE, n * TS, TS, seed=6, offset=OFFSET, half_period_shift=True)
    a = np.rint((plain.values - OFFSET) / AMPLITUDE)
    b = np.rint((shifted.values - OFFSET) / AMPLITUDE)
    cross = np.array([np.dot(a, np.roll(b, lag)) for lag in range(n)])
    assert np.flatnonzero(cross == n).tolist() == [n // 2]
    np.testing.assert_array_equal(np.delete(cross, n // 2), -1)


def test_prbs_half_period_shift_of_a_partial_period_keeps_two_levels_and_length():
    shifted = prbs(AMPLITUDE, 1000 * TS, TS, seed=4, offset=OFFSET, half_period_shift=True)
    assert shifted.num_samples == 1000
    np.testing.assert_allclose(
        np.sort(np.unique(shifted.values)), [OFFSET - AMPLITUDE, OFFSET + AMPLITUDE]
    )


# --- multilevel PRBS ------------------------------------------------------------------------------


def _holds(values):
    """(level of each hold, its length in samples), read from the changes of ``values``."""
    starts = np.concatenate([[0], np.flatnonzero(np.diff(values)) + 1])
    return values[starts], np.diff(np.append(starts, values.size))


def test_multilevel_levels_are_the_grid_each_equally_frequent():
    num_levels = 6
    signal = multilevel_prbs(
        AMPLITUDE,
        20_000 * TS,
        TS,
        seed=11,
        offset=OFFSET,
        num_levels=num_levels,
        hold_s=(3 * TS, 5 * TS),
    )
    assert signal.kind == "multilevel"
    grid = OFFSET + AMPLITUDE * np.linspace(-1.0, 1.0, num_levels)
    levels, _ = _holds(signal.values)
    index = np.rint((levels - grid[0]) / (grid[1] - grid[0])).astype(int)
    # Every value is a grid level (to rounding), and the ends are offset -+ A exactly.
    np.testing.assert_allclose(levels, grid[index], rtol=0.0, atol=1e-15)
    assert signal.values.min() == OFFSET - AMPLITUDE and signal.values.max() == OFFSET + AMPLITUDE
    # Each hold's level uniform over the levels: a chi-square test against equal counts.
    counts = np.bincount(index, minlength=num_levels)
    assert stats.chisquare(counts).pvalue > 1e-3


def test_multilevel_holds_are_uniform_over_their_range():
    shortest, longest = 3, 5
    signal = multilevel_prbs(
        AMPLITUDE,
        20_000 * TS,
        TS,
        seed=12,
        offset=OFFSET,
        num_levels=4,
        hold_s=(shortest * TS, longest * TS),
    )
    _, holds = _holds(signal.values)
    # The last hold is cut where the record ends. Two holds of one level in a row would read as
    # one of at least 2 * shortest > longest samples: none does, so every switch is a step.
    assert holds[:-1].min() == shortest and holds[:-1].max() == longest
    assert 1 <= holds[-1] <= longest
    counts = np.bincount(holds[:-1] - shortest)
    assert stats.chisquare(counts).pvalue > 1e-3


def test_multilevel_hold_seconds_become_whole_samples():
    # 1 s at 1/15 s is 15 samples despite 1 / (1/15) = 15.000000000000002.
    assert hold_samples((1.0, 40.0), 1.0 / 15.0) == (15, 600)
    assert hold_samples((0.25, 0.35), 0.1) == (3, 3)


@pytest.mark.parametrize(
    "hold_s",
    [(0.0, 1.0), (2.0, 1.0), (np.nan, 1.0), (1.0, np.inf), (0.005, 0.05), (0.025, 0.028), "1:2"],
)
def test_multilevel_rejects_bad_holds(hold_s):
    with pytest.raises(ValueError, match="hold_s must"):
        multilevel_prbs(AMPLITUDE, 100 * TS, TS, seed=0, hold_s=hold_s)


@pytest.mark.parametrize("num_levels", [1, 0, 2.5, True])
def test_multilevel_rejects_bad_level_counts(num_levels):
    with pytest.raises(ValueError, match="num_levels must be an integer of at least 2"):
        multilevel_prbs(AMPLITUDE, 100 * TS, TS, seed=0, num_levels=num_levels)


# --- multisine ----------------------------------------------------------------------------------


def test_multisine_single_line_is_a_sine_with_crest_sqrt_two():
    n = 400  # T = 4 s, grid spacing 0.25 Hz; only 1.0 Hz lies in the band
    signal = multisine(AMPLITUDE, n * TS, TS, seed=0, offset=OFFSET, frequency_band_hz=(0.9, 1.1))
    expected = OFFSET + AMPLITUDE * np.cos(2.0 * np.pi * 1.0 * signal.times_s)
    np.testing.assert_allclose(signal.values, expected, rtol=0.0, atol=1e-12)
    assert signal.crest_factor() == pytest.approx(math.sqrt(2.0), rel=1e-9)


@pytest.mark.parametrize("band_hz", [(0.5, 10.0), (1.0, 25.0), None])
def test_schroeder_crest_factor_beats_random_and_zero_phases(band_hz):
    n = 1000  # T = 10 s, grid spacing 0.1 Hz, Nyquist 50 Hz
    kwargs = dict(offset=OFFSET, frequency_band_hz=band_hz)
    schroeder = multisine(AMPLITUDE, n * TS, TS, seed=0, **kwargs)
    random = multisine(AMPLITUDE, n * TS, TS, seed=0, phases="random", **kwargs)
    zero = multisine(AMPLITUDE, n * TS, TS, seed=0, phases="zero", **kwargs)
    spectrum = np.abs(np.fft.rfft(zero.values - OFFSET))
    lines = int(np.sum(spectrum > 1e-6 * spectrum.max()))
    # Zero phases add K unit cosines in phase at t = 0: peak K, RMS sqrt(K / 2).
    assert zero.crest_factor() == pytest.approx(math.sqrt(2.0 * lines), rel=1e-9)
    assert schroeder.crest_factor() < 2.0
    assert schroeder.crest_factor() < 0.8 * random.crest_factor()
    assert schroeder.crest_factor() < zero.crest_factor()


@pytest.mark.parametrize("band_hz", [(0.5, 10.0), (2.05, 7.3), (12.0, 12.0)])
def test_multisine_spectrum_is_flat_inside_band_and_empty_outside(band_hz):
    n = 1000
    signal = multisine(AMPLITUDE, n * TS, TS, seed=0, offset=OFFSET, frequency_band_hz=band_hz)
    spectrum = np.abs(np.fft.rfft(signal.values - OFFSET))
    frequencies_hz = np.fft.rfftfreq(n, TS)
    inside = (frequencies_hz >= band_hz[0] - 1e-9) & (frequencies_hz <= band_hz[1] + 1e-9)
    assert np.any(inside)
    np.testing.assert_allclose(spectrum[inside], spectrum[inside][0], rtol=1e-9)
    assert np.max(spectrum[~inside]) < 1e-9 * spectrum[inside][0]


def test_multisine_peak_deviation_equals_amplitude_and_mean_is_offset():
    signal = multisine(AMPLITUDE, 1000 * TS, TS, seed=0, offset=OFFSET, frequency_band_hz=(1, 20))
    assert np.max(np.abs(signal.values - OFFSET)) == pytest.approx(AMPLITUDE, rel=1e-12)
    assert np.mean(signal.values) == pytest.approx(OFFSET, abs=1e-12)
    assert signal.kind == "multisine"


# --- dispatch -----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kind, design",
    [
        ("uniform", uniform_white_noise),
        ("prbs", prbs),
        ("multisine", multisine),
        ("multilevel", multilevel_prbs),
    ],
)
def test_dispatch_by_name_matches_direct_call(kind, design):
    kwargs = dict(amplitude=AMPLITUDE, duration_s=300 * TS, sample_period_s=TS, seed=3)
    np.testing.assert_array_equal(excitation_signal(kind, **kwargs).values, design(**kwargs).values)


def test_dispatch_rejects_unknown_kind():
    with pytest.raises(
        ValueError, match=r"kind must be one of \['multilevel', 'multisine', 'prbs', 'uniform'\]"
    ):
        excitation_signal("chirp", amplitude=AMPLITUDE)


# --- clipping -----------------------------------------------------------------------------------


def test_clip_to_paper_valve_range_and_fraction():
    # Uniform on [0, 200] mA clipped to the paper's [0, 165] mA: 35 / 200 of samples change.
    n = 50_000
    low, high = 0.0, 0.165
    signal = uniform_white_noise(0.100, n * TS, TS, seed=9, offset=0.100)
    expected = 0.035 / 0.200
    fraction = clipped_fraction(signal, low, high)
    assert abs(fraction - expected) < 5.0 * math.sqrt(expected * (1.0 - expected) / n)
    clipped = clip_to_valve_range(signal, low, high)
    assert clipped.values.min() >= low
    assert clipped.values.max() <= high
    assert np.mean(clipped.values != signal.values) == fraction
    assert clipped_fraction(clipped, low, high) == 0.0
    assert clipped.kind == signal.kind
    assert signal.values.max() > high  # the original is left unchanged


@pytest.mark.parametrize("low, high", [(0.2, 0.1), (0.1, 0.1), (np.nan, 0.1), (0.0, np.inf)])
def test_clip_rejects_bad_range(low, high):
    signal = uniform_white_noise(AMPLITUDE, 10 * TS, TS, seed=0)
    with pytest.raises(ValueError, match="low|high"):
        clip_to_valve_range(signal, low, high)
    with pytest.raises(ValueError, match="low|high"):
        clipped_fraction(signal, low, high)


# --- Drake source -------------------------------------------------------------------------------


def test_source_replays_samples_as_zero_order_hold():
    signal = prbs(AMPLITUDE, 50 * TS, TS, seed=1, offset=OFFSET)
    builder = DiagramBuilder()
    port = add_excitation_source(builder, signal, name="valve_current_excitation")
    diagram = builder.Build()
    source = diagram.GetSubsystemByName("valve_current_excitation")
    assert port.size() == 1
    context = diagram.CreateDefaultContext()
    source_context = source.GetMyContextFromRoot(context)

    def output_at(time_s):
        context.SetTime(time_s)
        return port.Eval(source_context)[0]

    for time_s, value in zip(signal.times_s, signal.values, strict=True):
        assert output_at(time_s) == value
        assert output_at(time_s + 0.5 * TS) == value
    # The last sample is held long after the signal ends.
    assert output_at(10.0 * signal.duration_s) == signal.values[-1]
    assert output_at(2e9) == signal.values[-1]


def test_source_rejects_non_signal():
    with pytest.raises(ValueError, match="signal must be an ExcitationSignal"):
        add_excitation_source(DiagramBuilder(), np.zeros(3))


# --- argument validation ------------------------------------------------------------------------


@pytest.mark.parametrize("design", [uniform_white_noise, prbs, multisine, multilevel_prbs])
@pytest.mark.parametrize(
    "overrides, match",
    [
        ({"amplitude": 0.0}, "amplitude must be positive"),
        ({"amplitude": -0.01}, "amplitude must be positive"),
        ({"amplitude": np.inf}, "amplitude must be a finite number"),
        ({"amplitude": np.nan}, "amplitude must be a finite number"),
        ({"duration_s": 1.5 * TS}, "duration_s must be at least 2 sample periods"),
        ({"duration_s": np.nan}, "duration_s must be a finite number"),
        ({"sample_period_s": 0.0}, "sample_period_s must be positive"),
        ({"sample_period_s": "0.01"}, "sample_period_s must be a finite number"),
        ({"seed": -1}, "seed must be a non-negative integer"),
        ({"seed": 1.5}, "seed must be a non-negative integer"),
        ({"seed": True}, "seed must be a non-negative integer"),
        ({"offset": np.nan}, "offset must be a finite number"),
    ],
)
def test_designs_reject_bad_common_arguments(design, overrides, match):
    kwargs = dict(amplitude=AMPLITUDE, duration_s=100 * TS, sample_period_s=TS, seed=0)
    kwargs.update(overrides)
    with pytest.raises(ValueError, match=match):
        design(**kwargs)


@pytest.mark.parametrize("clock_periods", [0, -2, 1.5, True])
def test_prbs_rejects_bad_clock_periods(clock_periods):
    with pytest.raises(ValueError, match="clock_periods must be a positive integer"):
        prbs(AMPLITUDE, 100 * TS, TS, seed=0, clock_periods=clock_periods)


@pytest.mark.parametrize(
    "band_hz, match",
    [
        ((0.0, 10.0), "0 < f_lo <= f_hi < Nyquist = 50.0 Hz"),
        ((10.0, 5.0), "0 < f_lo <= f_hi < Nyquist"),
        ((1.0, 50.0), "0 < f_lo <= f_hi < Nyquist"),
        ((1.0, 80.0), "0 < f_lo <= f_hi < Nyquist"),
        ((1.03, 1.07), "contains no line of the grid"),
        (5.0, "must be a pair"),
        ((1.0, 2.0, 3.0), "must be a pair"),
    ],
)
def test_multisine_rejects_bad_band(band_hz, match):
    with pytest.raises(ValueError, match=match):
        multisine(AMPLITUDE, 1000 * TS, TS, seed=0, frequency_band_hz=band_hz)


def test_multisine_rejects_unknown_phases():
    with pytest.raises(ValueError, match="phases must be one of"):
        multisine(AMPLITUDE, 100 * TS, TS, seed=0, phases="newman")


def test_theoretical_std_rejects_non_positive_amplitude():
    with pytest.raises(ValueError, match="amplitude must be positive"):
        theoretical_uniform_std(0.0)
