"""Open-loop excitation signals for identifying the valve-current-to-head-pitch dynamics.

The paper (Sec. IV-B, "Input Signal Design") drives the PVQ valve with a periodic, persistently
exciting uniform white noise whose amplitudes are clipped to the valve's range ([0, 165] mA), and
checks its spectrum for as small a crest factor as possible. The reasons carry over to any design:

- Persistent excitation: the input's spectrum must cover the band the model has to be accurate in,
  otherwise the prediction-error estimate is not identifiable there.
- Low crest factor (peak deviation over RMS deviation): the valve current is bounded, so a signal
  that puts more power into the plant for the same peak gives a better signal-to-noise ratio
  before clipping distorts it.

Four designs are offered, all returned as an :class:`ExcitationSignal` of uniformly sampled
currents in amperes:

- ``uniform``: i.i.d. uniform white noise on [offset - A, offset + A] (paper Eq. 22), whose
  standard deviation is A / sqrt(3) (Eq. 23, :func:`theoretical_uniform_std`).
- ``prbs``: a maximum-length binary sequence (crest factor about 1, flat spectrum over a period).
- ``multisine``: equal-amplitude sines on the period's frequency grid inside a chosen band, with
  Schroeder phases for a low crest factor.
- ``multilevel``: random levels of an evenly spaced grid held for random durations, so an
  identification sees the valve's whole static curve, not just two points of it (a Hammerstein
  fit needs that; paper Fig. 9).

The design functions are pure numpy/scipy; :func:`add_excitation_source` turns a designed signal
into a Drake ``TrajectorySource`` for simulation.
"""

import math
import numbers
from dataclasses import dataclass, replace

import numpy as np
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial
from scipy.signal import max_len_seq

from maskless.errors import ConfigError

# scipy.signal.max_len_seq ships feedback taps for registers of 2 to 32 bits.
_MIN_PRBS_REGISTER_BITS = 2
_MAX_PRBS_REGISTER_BITS = 32

# The source holds the last sample until this time (s), far beyond any experiment.
_HOLD_UNTIL_S = 1e9

# Tolerance when turning duration / period into a sample count, so 0.3 s / 0.1 s gives 3, not 2.
_SAMPLE_COUNT_RTOL = 1e-9

MULTISINE_PHASES = ("schroeder", "random", "zero")

# The multilevel design's defaults, chosen for the pneumatic plant (assets/pneumatic.yaml). Its
# slow pole's time constant, linearised with the outlet shut
# (pneumatic_design.linearize_pneumatic_plant), grows from 0.67 s at 62 mA to 9.0 s at 165 mA;
# its other modes (spool, head on the air spring) are faster than 0.05 s, beyond what the 15 Hz
# loop resolves. The longest hold, 40 s, is more than four of the slowest time constants, so holds
# at the top level can settle (e^-4 < 2 % left) and show the static gain; the shortest, 1 s, is
# about 1.5 of the fastest, so the record also holds short steps' transients.
# tests/test_excitation_run.py checks both against the linearised plant.
MULTILEVEL_HOLD_S = (1.0, 40.0)
# Over the whole 0-165 mA range, 12 levels are 15 mA apart, about three times the valve's
# hysteresis band (5 % of its 105 mA span), so every switch moves the spool; four of them lie
# below the 60 mA starting current, where no air flows.
MULTILEVEL_LEVELS = 12


@dataclass(frozen=True, eq=False)  # eq=False: element-wise array comparison has no single truth.
class ExcitationSignal:
    """A uniformly sampled excitation signal.

    The arrays are copied and made read-only, so the frozen dataclass is really immutable.

    Attributes:
        times_s: Sample instants (s), starting at 0 with a uniform step ``sample_period_s``.
        values: Signal value at each instant (A for a valve current), same length as ``times_s``.
        sample_period_s: Sample period Ts (s).
        kind: Name of the design that produced the signal ("uniform", "prbs", "multisine", ...).
    """

    times_s: np.ndarray
    values: np.ndarray
    sample_period_s: float
    kind: str

    def __post_init__(self):
        """Checks the samples (ValueError) and stores them as read-only float arrays."""
        _require_positive_finite("sample_period_s", self.sample_period_s)
        times_s = np.array(self.times_s, dtype=float)
        values = np.array(self.values, dtype=float)
        if times_s.ndim != 1 or values.ndim != 1:
            raise ConfigError(
                f"times_s and values must be 1-D arrays; got shapes {times_s.shape} and "
                f"{values.shape}"
            )
        if times_s.shape != values.shape:
            raise ConfigError(
                f"times_s and values must have the same length; got {times_s.size} and "
                f"{values.size}"
            )
        if times_s.size < 2:
            raise ConfigError(f"a signal needs at least 2 samples; got {times_s.size}")
        if not np.all(np.isfinite(values)):
            raise ConfigError("values must all be finite")
        expected_times_s = np.arange(times_s.size) * self.sample_period_s
        if not np.allclose(times_s, expected_times_s, rtol=0.0, atol=1e-9 * self.sample_period_s):
            raise ConfigError(
                f"times_s must start at 0 with uniform step sample_period_s = "
                f"{self.sample_period_s} s"
            )
        times_s.flags.writeable = False
        values.flags.writeable = False
        object.__setattr__(self, "times_s", times_s)
        object.__setattr__(self, "values", values)
        object.__setattr__(self, "sample_period_s", float(self.sample_period_s))

    @property
    def num_samples(self) -> int:
        """Number of samples N."""
        return int(self.values.size)

    @property
    def duration_s(self) -> float:
        """Span covered by the samples, N * Ts (s); each sample is held for one period."""
        return self.num_samples * self.sample_period_s

    def std(self) -> float:
        """Population standard deviation of the values (ddof = 0), in the values' unit.

        Compare with :func:`theoretical_uniform_std` for a uniform design (paper Eq. 23).
        """
        return float(np.std(self.values))

    def crest_factor(self) -> float:
        """Peak |x - mean| over RMS(x - mean), dimensionless.

        Measured about the sample mean, not about zero, because the valve current carries an
        offset (the operating point) that is not excitation. A square wave gives 1, a sine sqrt(2).

        Raises:
            ConfigError: If the signal is constant (zero RMS deviation).
        """
        deviation = self.values - np.mean(self.values)
        rms = math.sqrt(float(np.mean(deviation**2)))
        if rms == 0.0:
            raise ConfigError("crest factor is undefined for a constant signal (zero RMS)")
        return float(np.max(np.abs(deviation))) / rms


def theoretical_uniform_std(amplitude):
    """Standard deviation A / sqrt(3) of a uniform distribution on [-A, A] (paper Eq. 23).

    Args:
        amplitude: Half-width A of the distribution (any unit; the result has the same unit).
    """
    _require_positive_finite("amplitude", amplitude)
    return amplitude / math.sqrt(3.0)


def uniform_white_noise(
    amplitude, duration_s, sample_period_s, seed, offset=0.0
) -> ExcitationSignal:
    """I.i.d. uniform white noise on [offset - A, offset + A] (paper Eq. 22).

    The density is 1 / (2A) on the interval, so the standard deviation is A / sqrt(3) (Eq. 23).
    The paper used a long-cycle generator; numpy's ``default_rng`` (PCG64, period 2**128) plays
    that role, seeded so a record can be regenerated exactly.

    Args:
        amplitude: Half-width A of the distribution (A, amperes for a valve current).
        duration_s: Signal length (s); N = floor(duration_s / sample_period_s) samples.
        sample_period_s: Sample period Ts (s).
        seed: Non-negative integer seed of ``np.random.default_rng``.
        offset: Centre of the distribution, the operating point (A).
    """
    num_samples = _validated_common(amplitude, duration_s, sample_period_s, seed, offset)
    rng = np.random.default_rng(seed)
    values = rng.uniform(offset - amplitude, offset + amplitude, size=num_samples)
    # uniform() draws from [low, high); a clip guards the closed support against rounding.
    values = np.clip(values, offset - amplitude, offset + amplitude)
    return sampled_signal(values, sample_period_s, "uniform")


def prbs(
    amplitude,
    duration_s,
    sample_period_s,
    seed,
    offset=0.0,
    clock_periods=1,
    half_period_shift=False,
) -> ExcitationSignal:
    """A maximum-length pseudo-random binary sequence with values offset +/- A.

    The register length n is the smallest (at least 2, at most 32) whose period 2**n - 1 bits
    covers the duration, so the signal is one period or a prefix of one; beyond 32 bits the
    sequence repeats. Over a full period an MLS has one more +1 than -1 and a two-valued circular
    autocorrelation, hence a flat spectrum, and its crest factor is about 1 (the lowest possible).

    Args:
        amplitude: Deviation A of each level from the offset (A).
        duration_s: Signal length (s); N = floor(duration_s / sample_period_s) samples.
        sample_period_s: Sample period Ts (s).
        seed: Non-negative integer; chooses the register's non-zero initial state, which shifts
            the sequence circularly.
        offset: Mid level, the operating point (A).
        clock_periods: Samples each bit is held (positive integer); larger values move the
            excitation power to lower frequencies (first spectral null at 1 / (clock_periods Ts)).
        half_period_shift: Start the same sequence P // 2 bits later (P its period). Over a
            period the two sequences' circular cross-correlation is then the MLS's
            autocorrelation shifted by P // 2: -1 / P at every lag but P // 2 (half a period),
            so a second input that no model's lags can confuse with the first (another seed
            would shift the sequence by a random, possibly short, lag).
    """
    num_samples = _validated_common(amplitude, duration_s, sample_period_s, seed, offset)
    _require_positive_int("clock_periods", clock_periods)
    num_bits = -(-num_samples // clock_periods)  # ceil: the last bit may be cut short
    register_bits = _MIN_PRBS_REGISTER_BITS
    while 2**register_bits - 1 < num_bits and register_bits < _MAX_PRBS_REGISTER_BITS:
        register_bits += 1
    # Draw the initial state as an integer in [1, 2**n - 1], so it is never the all-zero state
    # (which the register cannot leave).
    rng = np.random.default_rng(seed)
    state_int = int(rng.integers(1, 2**register_bits))
    state = np.array([(state_int >> i) & 1 for i in range(register_bits)], dtype=np.int8)
    period_bits = 2**register_bits - 1
    if half_period_shift:
        # The whole period (shorter than twice the bits needed), started half of it later.
        bits = np.roll(max_len_seq(register_bits, state=state)[0], -(period_bits // 2))
    else:
        bits, _ = max_len_seq(register_bits, state=state, length=min(num_bits, period_bits))
    bits = np.resize(bits, num_bits)  # repeats the period in the (impractical) > 32-bit case
    levels = np.repeat(2.0 * bits.astype(float) - 1.0, clock_periods)[:num_samples]
    return sampled_signal(offset + amplitude * levels, sample_period_s, "prbs")


def multisine(
    amplitude,
    duration_s,
    sample_period_s,
    seed,
    offset=0.0,
    frequency_band_hz=None,
    phases="schroeder",
) -> ExcitationSignal:
    """A sum of equal-amplitude sines on the signal period's frequency grid.

    The N samples span one period T = N Ts, and every sine sits on the grid k / T (k = 1, 2, ...)
    inside the band, so the signal is exactly periodic: repeated, it has no leakage and its
    spectrum is zero outside the band.

    Schroeder phases phi_k = -pi k (k - 1) / K (k = 1..K, equal amplitudes) are a closed-form
    choice that spreads the sines' peaks in time, giving a crest factor of about 1.5 to 1.9 (a
    single sine has sqrt(2)) rather than the sqrt(2K) of zero phases. The result is scaled so
    max |x - offset| equals the amplitude.

    Args:
        amplitude: Peak deviation from the offset (A).
        duration_s: Signal length, one period (s); N = floor(duration_s / sample_period_s).
        sample_period_s: Sample period Ts (s).
        seed: Non-negative integer; used only when ``phases == "random"`` (the Schroeder and zero
            phases are deterministic and ignore it).
        offset: Operating point the sines oscillate about (A).
        frequency_band_hz: (f_lo, f_hi) in Hz with 0 < f_lo <= f_hi < 1 / (2 Ts); grid lines in
            the closed band are excited. None excites every grid line below the Nyquist frequency.
        phases: "schroeder" (low crest factor), "random" (uniform on [0, 2 pi), seeded) or
            "zero" (all phases 0, the worst case, for comparison).
    """
    num_samples = _validated_common(amplitude, duration_s, sample_period_s, seed, offset)
    if phases not in MULTISINE_PHASES:
        raise ConfigError(f"phases must be one of {MULTISINE_PHASES}; got {phases!r}")
    period_s = num_samples * sample_period_s
    nyquist_hz = 0.5 / sample_period_s
    # Grid lines strictly between 0 Hz and Nyquist: a sine at Nyquist would sample as +/-cos only.
    harmonics = np.arange(1, (num_samples + 1) // 2)
    if frequency_band_hz is None:
        selected = harmonics
    else:
        f_lo, f_hi = validated_band(frequency_band_hz, nyquist_hz)
        grid_hz = harmonics / period_s
        tolerance_hz = 1e-9 / period_s  # band edges that fall on a grid line are included
        selected = harmonics[(grid_hz >= f_lo - tolerance_hz) & (grid_hz <= f_hi + tolerance_hz)]
    if selected.size == 0:
        raise ConfigError(
            f"frequency_band_hz {frequency_band_hz} contains no line of the grid k / T with "
            f"spacing {1.0 / period_s} Hz; widen the band or lengthen duration_s"
        )
    count = selected.size
    if phases == "schroeder":
        index = np.arange(1, count + 1)
        phase = -np.pi * index * (index - 1) / count
    elif phases == "random":
        phase = np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, size=count)
    else:
        phase = np.zeros(count)
    sample_index = np.arange(num_samples)
    # Integer harmonic times sample index, reduced mod N, keeps the phase argument exact.
    cycles = np.outer(sample_index, selected) % num_samples / num_samples
    waveform = np.cos(2.0 * np.pi * cycles + phase).sum(axis=1)
    waveform *= amplitude / np.max(np.abs(waveform))
    return sampled_signal(offset + waveform, sample_period_s, "multisine")


def multilevel_prbs(
    amplitude,
    duration_s,
    sample_period_s,
    seed,
    offset=0.0,
    num_levels=MULTILEVEL_LEVELS,
    hold_s=MULTILEVEL_HOLD_S,
) -> ExcitationSignal:
    """Random levels held for random durations: an amplitude-rich excitation for a Hammerstein fit.

    A binary PRBS visits two currents, so it shows the valve's static curve at two points; a
    Hammerstein fit (paper Fig. 9) must see the whole curve, from below the starting current
    (no flow) up to saturation. Design choices, and why:

    - Levels: ``num_levels`` evenly spaced values from offset - A to offset + A, ends included.
      A fixed grid visits every level many times (noise and valve hysteresis average out, and
      each level is reached from above and from below) and makes the level distribution
      checkable. Each hold's level is drawn uniformly from the levels other than the current
      one, so every switch is a real step and a hold lasts exactly its drawn time; that chain's
      stationary distribution is uniform, so over many holds each level is equally frequent.
      Space the levels wider than the valve's hysteresis band, so every switch moves the spool.
    - Hold times: whole samples drawn uniformly from [ceil(min / Ts), floor(max / Ts)]. Long
      holds let the output settle, which is what shows the static gain at a level: make the
      longest about four of the plant's slowest time constants (e^-4 < 2 % left). Short holds
      put power at the frequencies of the dynamics: make the shortest about the plant's fastest
      time constant of interest. The defaults are the pneumatic plant's (``MULTILEVEL_HOLD_S``
      and ``MULTILEVEL_LEVELS`` give its measured time constants and hysteresis).

    The draws come from ``np.random.default_rng(seed)``: first the holds, then the first level,
    then the steps between levels, so the same seed gives the same signal bit for bit. The last
    hold is cut short where the duration ends.

    Args:
        amplitude: Half the span of the levels, A (A).
        duration_s: Signal length (s); N = floor(duration_s / sample_period_s) samples.
        sample_period_s: Sample period Ts (s).
        seed: Non-negative integer seed of ``np.random.default_rng``.
        offset: Centre of the levels (A).
        num_levels: Number of levels, an integer of at least 2.
        hold_s: (shortest, longest) hold in s, with Ts <= shortest <= longest.
    """
    num_samples = _validated_common(amplitude, duration_s, sample_period_s, seed, offset)
    integer = not isinstance(num_levels, bool) and isinstance(num_levels, numbers.Integral)
    if not integer or num_levels < 2:
        raise ConfigError(f"num_levels must be an integer of at least 2; got {num_levels!r}")
    rng = np.random.default_rng(seed)
    holds = random_holds(rng, num_samples, hold_s, sample_period_s)
    num_holds = holds.size
    first = rng.integers(num_levels)
    # A step of 1 to L - 1 levels (mod L) never lands on the level it leaves.
    steps = rng.integers(1, num_levels, size=num_holds - 1)
    level_index = (first + np.concatenate([[0], np.cumsum(steps)])) % num_levels
    levels = np.linspace(offset - amplitude, offset + amplitude, num_levels)
    values = np.repeat(levels[level_index], holds)[:num_samples]
    return sampled_signal(values, sample_period_s, "multilevel")


def random_holds(rng, num_samples, hold_s, sample_period_s) -> np.ndarray:
    """Hold lengths in whole samples, drawn uniformly from ``hold_samples``' range.

    Enough of them to fill ``num_samples`` even if every one is the shortest; the last may run
    past the end, for the caller to cut.

    Args:
        rng: the ``np.random.Generator`` the holds are drawn from (one draw of the array).
        num_samples: the record's length N.
        hold_s: (shortest, longest) hold (s), as ``hold_samples`` checks it.
        sample_period_s: Sample period Ts (s).
    """
    shortest, longest = hold_samples(hold_s, sample_period_s)
    return rng.integers(shortest, longest + 1, size=-(-num_samples // shortest))


def hold_samples(hold_s, sample_period_s) -> tuple[int, int]:
    """(shortest, longest) hold of a multilevel design in whole samples, checked.

    Args:
        hold_s: (shortest, longest) hold (s); both at least one sample, shortest <= longest.
        sample_period_s: Sample period Ts (s).
    """
    try:
        shortest_s, longest_s = (float(h) for h in hold_s)
    except (TypeError, ValueError):
        raise ConfigError(
            f"hold_s must be a pair (shortest, longest) in s; got {hold_s!r}"
        ) from None
    finite = math.isfinite(shortest_s) and math.isfinite(longest_s)
    at_least_a_sample = finite and shortest_s >= sample_period_s * (1.0 - _SAMPLE_COUNT_RTOL)
    # The same forgiveness as sample_count, upwards: 1 s at 1/15 s is 15 samples, not 16.
    shortest = math.ceil(shortest_s / sample_period_s * (1.0 - _SAMPLE_COUNT_RTOL)) if finite else 0
    longest = sample_count(longest_s, sample_period_s) if finite else 0
    if not (at_least_a_sample and shortest <= longest):
        raise ConfigError(
            f"hold_s must satisfy {sample_period_s:g} s (one sample) <= shortest <= longest, "
            f"with a whole sample between them; got {hold_s!r}"
        )
    return shortest, longest


_DESIGNS = {
    "multilevel": multilevel_prbs,
    "multisine": multisine,
    "prbs": prbs,
    "uniform": uniform_white_noise,
}


def excitation_signal(kind, **kwargs) -> ExcitationSignal:
    """Designs a signal by name, e.g. from a configuration file.

    Args:
        kind: "uniform", "prbs", "multisine" or "multilevel".
        **kwargs: Arguments of :func:`uniform_white_noise`, :func:`prbs`, :func:`multisine` or
            :func:`multilevel_prbs`.
    """
    if kind not in _DESIGNS:
        raise ConfigError(f"kind must be one of {sorted(_DESIGNS)}; got {kind!r}")
    return _DESIGNS[kind](**kwargs)


def clip_to_valve_range(signal, low, high) -> ExcitationSignal:
    """A copy of ``signal`` with values clipped to [low, high].

    The paper clipped its uniform noise to the valve's [0, 165] mA. Clipping flattens the
    distribution and adds harmonics, so check :func:`clipped_fraction` before an experiment.

    Args:
        signal: An :class:`ExcitationSignal`.
        low: Smallest allowed value (A).
        high: Largest allowed value (A), greater than ``low``.
    """
    _validated_range(low, high)
    return replace(signal, values=np.clip(signal.values, low, high))


def clipped_fraction(signal, low, high) -> float:
    """Fraction of samples of ``signal`` outside [low, high], i.e. changed by clipping (0 to 1).

    Args:
        signal: An :class:`ExcitationSignal`.
        low: Smallest allowed value (A).
        high: Largest allowed value (A), greater than ``low``.
    """
    _validated_range(low, high)
    outside = (signal.values < low) | (signal.values > high)
    return float(np.mean(outside))


def add_excitation_source(
    builder: DiagramBuilder, signal: ExcitationSignal, name="excitation"
) -> OutputPort:
    """Adds a Drake source that replays ``signal`` as a zero-order hold and returns its output.

    Sample i is output on [t_i, t_i + Ts); the last sample is held until t = 1e9 s and beyond, so
    a simulation longer than the signal sees a constant input rather than a jump.

    Args:
        builder: The DiagramBuilder to add the ``TrajectorySource`` to.
        signal: The :class:`ExcitationSignal` to replay (values in A).
        name: Name of the added system (unique within the builder).

    Returns:
        The source's 1-element output port (the valve current, A).
    """
    if not isinstance(signal, ExcitationSignal):
        raise ConfigError(f"signal must be an ExcitationSignal; got {type(signal).__name__}")
    breaks_s = np.append(signal.times_s, _HOLD_UNTIL_S)
    samples = np.append(signal.values, signal.values[-1]).reshape(1, -1)
    trajectory = PiecewisePolynomial.ZeroOrderHold(breaks_s, samples)
    source = builder.AddNamedSystem(name, TrajectorySource(trajectory))
    return source.get_output_port()


def sampled_signal(values, sample_period_s, kind) -> ExcitationSignal:
    """``values`` as a signal sampled every ``sample_period_s`` from 0, named ``kind``."""
    times_s = np.arange(values.size) * sample_period_s
    return ExcitationSignal(times_s, values, sample_period_s, kind)


def sample_count(duration_s, sample_period_s) -> int:
    """The samples N = floor(duration_s / sample_period_s) a design of that length has.

    The ratio's rounding error is forgiven (0.3 s / 0.1 s gives 3, not 2).
    """
    return math.floor(duration_s / sample_period_s * (1.0 + _SAMPLE_COUNT_RTOL))


def _validated_common(amplitude, duration_s, sample_period_s, seed, offset):
    """Checks the arguments every design shares and returns the sample count N."""
    _require_positive_finite("amplitude", amplitude)
    _require_positive_finite("sample_period_s", sample_period_s)
    _require_finite("duration_s", duration_s)
    _require_finite("offset", offset)
    if isinstance(seed, bool) or not isinstance(seed, numbers.Integral) or seed < 0:
        raise ConfigError(f"seed must be a non-negative integer; got {seed!r}")
    num_samples = sample_count(duration_s, sample_period_s)
    if num_samples < 2:
        raise ConfigError(
            f"duration_s must be at least 2 sample periods ({2 * sample_period_s} s); "
            f"got {duration_s}"
        )
    return num_samples


def validated_band(frequency_band_hz, nyquist_hz):
    """(f_lo, f_hi) of a multisine band, checked: 0 < f_lo <= f_hi < the Nyquist frequency."""
    try:
        f_lo, f_hi = (float(f) for f in frequency_band_hz)
    except (TypeError, ValueError):
        raise ConfigError(
            f"frequency_band_hz must be a pair (f_lo, f_hi) in Hz; got {frequency_band_hz!r}"
        ) from None
    if not (0.0 < f_lo <= f_hi < nyquist_hz):
        raise ConfigError(
            f"frequency_band_hz must satisfy 0 < f_lo <= f_hi < Nyquist = {nyquist_hz} Hz; "
            f"got {frequency_band_hz!r}"
        )
    return f_lo, f_hi


def _validated_range(low, high):
    _require_finite("low", low)
    _require_finite("high", high)
    if not low < high:
        raise ConfigError(f"low must be less than high; got low = {low}, high = {high}")


def _require_finite(name, value):
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
        raise ConfigError(f"{name} must be a finite number; got {value!r}")


def _require_positive_finite(name, value):
    _require_finite(name, value)
    if value <= 0:
        raise ConfigError(f"{name} must be positive; got {value!r}")


def _require_positive_int(name, value):
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ConfigError(f"{name} must be a positive integer; got {value!r}")
