"""What a record can and cannot support, judged before (and, for integrators, after) fitting.

Five diagnostics, each with its figures in the report's JSON and, where it fires, a warning:

- excitation: the order of the input's excitation (how many independent directions its windows
  span) against the 2n an order-n model needs, and whether that excitation persists through the
  record or comes from a few transients (three short pulses, one step);
- offset and drift: how much of each signal is a constant or a straight line, and which
  ``--detrend`` removes it;
- integrators: fitted poles so close to z = 1 that the record cannot tell them from an integrator;
- stuck signals: the longest stretch over which a signal holds one exact value (a constant signal
  is refused outright, naming the signal and its source);
- clipping: the share of input samples piled up at the input's minimum and maximum.

Each threshold below says why it is where it is. Those marked "convention" are choices, as the
report's verdict thresholds are, not derived values.
"""

from dataclasses import asdict, dataclass

import numpy as np

from maskless.errors import RecordError

# A signal whose spread is below this fraction of its magnitude is constant: one count of a 32-bit
# converter's full scale is 2⁻³² ≈ 2.3e-10 of it, so no measured variation is smaller; what
# remains is arithmetic rounding.
CONSTANT_RELATIVE_SPREAD = 1e-10
# An input direction carrying less than this fraction of the input's largest windowed power is
# not excited. A sum of k sinusoids spans exactly 2k directions, its others are rounding; white
# noise spans all of them at nearly equal power. 1e-4 (40 dB below the strongest direction) sits
# far above rounding and below the weakest real direction of a binary signal held 10 samples a
# bit (convention; tests/test_data_diagnostics.py checks both).
EXCITATION_TOLERANCE = 1e-4
# An order-n model has 2n transfer-function coefficients; an input persistently exciting of order
# 2n determines them (Söderström and Stoica, System Identification, 1989).
EXCITATION_ORDER_PER_MODEL_ORDER = 2
# Persistence: the part is cut into this many stretches, each judged alone; a stretch is
# persistent when it alone excites every direction the whole part does. Excitation confined to
# fewer than half of them (pulses, a step) is transient, not persistent (convention).
EXCITATION_STRETCHES = 10
PERSISTENT_SHARE = 0.5
# A stretch needs this many windows per tested direction for its covariance to mean anything.
WINDOWS_PER_DIRECTION = 10
# The share of a signal's variance about its mean that a straight line must carry to be called a
# drift (convention: a quarter, so the trend is a visible part of what the fit must explain).
DRIFT_SHARE = 0.25
# ... and how many standard errors its slope must stand from zero. A slow process wanders, and
# over a record a few of its time constants long a line fits part of that wandering; so the
# standard error counts the residuals' correlation, with the effective sample count
# N (1 - r1) / (1 + r1) of lag-1 autocorrelation r1 (Santer et al., J. Geophys. Res. 105, 2000).
# Three standard errors is a convention.
DRIFT_T_STATISTIC = 3.0
# The share of a signal's mean square that a constant must carry to be called an offset, for a
# record fitted with --detrend none (convention, as DRIFT_SHARE).
OFFSET_SHARE = 0.25
# A pole p near z = 1 has a time constant of about 1 / |1 - p| samples. Within 1e-3 of 1 that is
# at least 1000 samples, and within 4 / N of 1 over a quarter of the N-sample estimation part (a
# response needs four time constants to settle within 2 %): either way the record shows a ramp,
# indistinguishable from an integrator, and the DC gain is set by how far from 1 the fit happened
# to put the pole. The distance used is the larger of the two.
INTEGRATOR_POLE_DISTANCE = 1e-3
SETTLING_TIME_CONSTANTS = 4.0
# A measured output holds one exact value only while its sensor holds a reading (a few samples
# at a time); held over a twentieth of the record it is stuck, or too coarsely resolved there.
STUCK_OUTPUT_SHARE = 0.05
# An input is held by design (steps, PRBS bits): only a value held over half the record is named.
STUCK_INPUT_SHARE = 0.5
# Clipping is named when more than this share of the input sits at one limit (convention: 5 %,
# the two-sided tail of a Gaussian beyond ±1.96 σ, where the limiter shapes the input's
# distribution), and only when samples pile up there: at least this many times the share of the
# input's most common value between its limits. Two-level and multilevel signals (PRBS, pulses)
# sit at their extremes by design and are not clipped.
CLIPPING_SHARE = 0.05
CLIPPING_PILE_UP = 10.0


@dataclass(frozen=True)
class Excitation:
    """The input's order of excitation on the estimation part, against each model order.

    Attributes:
        tested_order: m, the window length tested (2n for the largest order n asked).
        order: how many of the m directions the input excites (eigenvalues of its m x m
            covariance above ``EXCITATION_TOLERANCE`` of the largest).
        stretches: how many stretches the part was cut into (0: too short to judge persistence).
        persistent_stretches: how many of them alone excite as many directions as the part.
        too_poor_for_orders: the model orders this excitation cannot support.
    """

    tested_order: int
    order: int
    stretches: int
    persistent_stretches: int
    too_poor_for_orders: tuple[int, ...]


@dataclass(frozen=True)
class Trend:
    """How much of one signal is a constant and a straight line.

    Attributes:
        mean: the signal's mean (its unit).
        slope_per_sample: its least-squares line's slope (its unit per sample).
        offset_share: mean² / mean square: the share of the signal's power that is constant.
        drift_share: the share of its variance about the mean that the line carries.
        slope_t_statistic: the slope in standard errors, corrected for the residuals'
            correlation (see ``DRIFT_T_STATISTIC``).
    """

    mean: float
    slope_per_sample: float
    offset_share: float
    drift_share: float
    slope_t_statistic: float

    @property
    def drifts(self) -> bool:
        """Whether the line is a drift: large (``DRIFT_SHARE``) and sure (``DRIFT_T_STATISTIC``)."""
        return self.drift_share > DRIFT_SHARE and abs(self.slope_t_statistic) > DRIFT_T_STATISTIC


@dataclass(frozen=True)
class Hold:
    """The longest stretch over which a signal holds one exact value.

    Attributes:
        value: the value held (the signal's unit).
        start: its first sample.
        samples: how many samples it lasts.
        share: samples / the record's length.
    """

    value: float
    start: int
    samples: int
    share: float


@dataclass(frozen=True)
class Clipping:
    """The input's samples at its limits.

    Attributes:
        minimum, maximum: the input's limits in the record (its unit).
        share_at_minimum, share_at_maximum: the share of samples exactly at each.
        largest_interior_share: the share of the most common value between the limits (0 when
            there is none: a two-level signal).
        clipped_at: "minimum", "maximum", both, or neither, by the thresholds above.
    """

    minimum: float
    maximum: float
    share_at_minimum: float
    share_at_maximum: float
    largest_interior_share: float
    clipped_at: tuple[str, ...]


@dataclass(frozen=True)
class Integrator:
    """A fitted pole near z = 1 (see ``integrator_distance``).

    Attributes:
        order: the order of the model holding it.
        pole: (real, imaginary).
        distance_to_1: |1 - pole|.
        threshold: the distance within which it was named.
    """

    order: int
    pole: tuple[float, float]
    distance_to_1: float
    threshold: float


@dataclass(frozen=True)
class RecordDiagnostics:
    """What the whole record shows before any part is chosen or detrended.

    Attributes:
        units: (input unit, output unit) as given ("" when not given).
        detrend: the ``--detrend`` the fit uses ("mean", "linear" or "none").
        input_trend, output_trend: each signal's offset and drift.
        suggested_detrend: the ``--detrend`` that removes what the chosen one leaves (None when
            nothing is left).
        input_hold, output_hold: each signal's longest hold.
        clipping: the input's samples at its limits.
    """

    units: tuple[str, str]
    detrend: str
    input_trend: Trend
    output_trend: Trend
    suggested_detrend: str | None
    input_hold: Hold
    output_hold: Hold
    clipping: Clipping


@dataclass(frozen=True)
class DataDiagnostics:
    """Every diagnostic of one identification, and the warnings they raise.

    Attributes:
        record: the whole record's diagnostics (None when only the parts were given).
        estimation_samples: N, the estimation part's length.
        excitation: the estimation part's excitation.
        integrators: the fitted poles near z = 1.
        warnings: one sentence per diagnostic that fired.
    """

    record: RecordDiagnostics | None
    estimation_samples: int
    excitation: Excitation
    integrators: tuple[Integrator, ...]
    warnings: tuple[str, ...]

    def as_dict(self) -> dict:
        """The report's "diagnostics" entry (JSON-ready), with the thresholds it judged by."""
        return {
            "thresholds": {
                "excitation_tolerance": EXCITATION_TOLERANCE,
                "excitation_order_per_model_order": EXCITATION_ORDER_PER_MODEL_ORDER,
                "persistent_share": PERSISTENT_SHARE,
                "drift_share": DRIFT_SHARE,
                "drift_t_statistic": DRIFT_T_STATISTIC,
                "offset_share": OFFSET_SHARE,
                "integrator_pole_distance": integrator_distance(self.estimation_samples),
                "stuck_output_share": STUCK_OUTPUT_SHARE,
                "stuck_input_share": STUCK_INPUT_SHARE,
                "clipping_share": CLIPPING_SHARE,
                "clipping_pile_up": CLIPPING_PILE_UP,
            },
            "record": None if self.record is None else _json_ready(asdict(self.record)),
            "excitation": _json_ready(asdict(self.excitation)),
            "integrators": [_json_ready(asdict(integrator)) for integrator in self.integrators],
            "warnings": list(self.warnings),
        }


def _json_ready(value):
    """``value`` as JSON reads it back: tuples as lists, numpy numbers as Python's."""
    if isinstance(value, dict):
        return {key: _json_ready(item) for key, item in value.items()}
    if isinstance(value, tuple | list):
        return [_json_ready(item) for item in value]
    return value.item() if isinstance(value, np.generic) else value


def format_pole(pole: tuple[float, float]) -> str:
    """A pole (real, imaginary) as text: a real pole as one number."""
    return f"{pole[0]:.6g}" if pole[1] == 0 else f"{complex(*pole):.6g}"


def is_constant(signal: np.ndarray, scale: float = 0.0) -> bool:
    """Whether ``signal`` varies by no more than ``CONSTANT_RELATIVE_SPREAD`` of its size or scale.

    Its size is its largest magnitude.

    Args:
        signal: the samples (any unit), at least one.
        scale: the spread of the signals it shares a unit with (the other valve's current), if
            any. A valve never opened but for one rounding error (1e-17 A in a closed loop's
            record) varies by all of its own magnitude, and by nothing of the other's.
    """
    reference = max(float(np.max(np.abs(signal))), scale)
    return bool(np.ptp(signal) <= CONSTANT_RELATIVE_SPREAD * reference)


def widest_spread(u: np.ndarray) -> float:
    """The largest spread of the columns of ``u`` (N, inputs): ``is_constant``'s ``scale``."""
    return float(np.max(np.ptp(u, axis=0)))


def refuse_constant(
    signal: np.ndarray, name: str, source: str, unit: str = "", scale: float = 0.0
) -> None:
    """A one-line RecordError naming ``name`` ("input", "output") and ``source`` if it is constant.

    Args:
        signal: the samples.
        name: which signal it is.
        source: where it came from (a file, TOPIC:FIELD, or the argument's name).
        unit: its unit, as given ("" when not given).
        scale: as ``is_constant`` takes it.
    """
    if not is_constant(signal, scale):
        return
    spread = np.ptp(signal)
    held = (
        f"{_with_unit(signal[0], unit)} over all {signal.size} samples, spread {spread:.3g}"
        if is_constant(signal)
        else f"it varies by {spread:.3g} over {signal.size} samples: rounding, beside the "
        f"{_with_unit(scale, unit)} the widest input spans"
    )
    raise RecordError(
        f"{source}: the {name} is constant ({held}): there is nothing to identify from it"
    )


def refuse_unfit_part(
    what: str, part: slice, output: np.ndarray, output_source: str, needed: int, needing: str
) -> None:
    """A one-line RecordError for a part of a record no fit can use.

    Args:
        what: the part as the refusal names it (its flag, or the part and where it came from).
        part: the part, a slice of ``output``.
        output: the whole record's output.
        output_source: where the output came from (a file, TOPIC:FIELD).
        needed: the fewest samples the part may hold, for ``needing`` (say "order 2 with pem").
        needing: what needs them.
    """
    size = part.stop - part.start
    if size < needed:
        raise RecordError(f"{what} selects {size} samples; {needing} needs at least {needed}")
    # Every fit figure divides by the output's spread over the part (the naive baseline's from
    # its second sample): a constant output leaves them undefined.
    if is_constant(output[part][1:]):
        raise RecordError(
            f"{what} selects samples {part.start}:{part.stop} of {output_source}, where the "
            "output is constant: no fit is defined on it"
        )


def excitation(u: np.ndarray, orders: list[int]) -> Excitation:
    """The order of excitation of the input ``u`` (one part), against each of ``orders``.

    The covariance is that of the windows lying wholly inside the part, about the part's mean: no
    zero padding, whose edges would add directions a line spectrum does not have.

    Args:
        u: the part's input samples (any unit).
        orders: the model orders n to judge it for (positive).
    """
    tested = EXCITATION_ORDER_PER_MODEL_ORDER * max(orders)
    largest, order = _excited_directions(u - u.mean(), tested, None)
    stretches = min(EXCITATION_STRETCHES, u.size // (WINDOWS_PER_DIRECTION * tested))
    persistent = 0
    if stretches >= 2:
        for stretch in np.array_split(u, stretches):
            # Each stretch about its own mean, judged against the whole part's strongest
            # direction: a quiet stretch excites nothing, however its few values are spread.
            persistent += _excited_directions(stretch - stretch.mean(), tested, largest)[1] >= order
    transient = stretches >= 2 and persistent < PERSISTENT_SHARE * stretches
    too_poor = tuple(n for n in orders if transient or order < EXCITATION_ORDER_PER_MODEL_ORDER * n)
    return Excitation(tested, order, stretches, persistent, too_poor)


def _excited_directions(
    deviations: np.ndarray, length: int, reference: float | None
) -> tuple[float, int]:
    """(largest eigenvalue, eigenvalues above tolerance) of the windows' covariance."""
    windows = np.lib.stride_tricks.sliding_window_view(deviations, length)
    eigenvalues = np.linalg.eigvalsh(windows.T @ windows / windows.shape[0])
    largest = float(eigenvalues[-1]) if reference is None else reference
    return largest, int(np.sum(eigenvalues > EXCITATION_TOLERANCE * largest))


def trend(signal: np.ndarray) -> Trend:
    """The offset and drift of one signal (see ``Trend``).

    Args:
        signal: the samples as read (any unit), at least two.
    """
    mean_square = float(np.mean(signal**2))
    offset_share = float(signal.mean() ** 2 / mean_square) if mean_square > 0 else 0.0
    if np.ptp(signal) == 0:  # no line to fit (its share of a zero variance is undefined)
        return Trend(float(signal.mean()), 0.0, offset_share, 0.0, 0.0)
    samples = np.arange(signal.size)
    # numpy's line and its covariance, not scipy.stats.linregress: importing scipy.stats takes
    # 0.7 s of the second `maskless identify` has (issue 14).
    if signal.size > 2:
        (slope, intercept), covariance = np.polyfit(samples, signal, 1, cov=True)
        line_standard_error = float(np.sqrt(covariance[0, 0]))
    else:  # two points: the line through them, exactly
        (slope, intercept), line_standard_error = np.polyfit(samples, signal, 1), 0.0
    residuals = signal - (intercept + slope * samples)
    deviations = signal - signal.mean()
    lag_1 = float(np.dot(residuals[1:], residuals[:-1]) / max(np.dot(residuals, residuals), 1e-300))
    # Fewer independent samples widen the standard error by sqrt(N / N_eff).
    widening = np.sqrt((1 + lag_1) / max(1 - lag_1, np.finfo(float).eps))
    standard_error = line_standard_error * widening
    return Trend(
        mean=float(signal.mean()),
        slope_per_sample=float(slope),
        offset_share=offset_share,
        drift_share=float(1.0 - np.dot(residuals, residuals) / np.dot(deviations, deviations)),
        slope_t_statistic=float(slope / standard_error) if standard_error > 0 else np.inf,
    )


def longest_hold(signal: np.ndarray) -> Hold:
    """The longest run of one exact value in ``signal``.

    Args:
        signal: the samples as read (any unit), at least one.
    """
    starts = np.flatnonzero(np.r_[True, signal[1:] != signal[:-1]])
    lengths = np.diff(np.r_[starts, signal.size])
    longest = int(np.argmax(lengths))
    start = int(starts[longest])
    samples = int(lengths[longest])
    return Hold(float(signal[start]), start, samples, samples / signal.size)


def clipping(u: np.ndarray) -> Clipping:
    """The input's samples at its limits (see ``Clipping``).

    Args:
        u: the input as read (any unit), at least one sample.
    """
    values, counts = np.unique(u, return_counts=True)
    shares = counts / u.size
    interior = float(shares[1:-1].max()) if values.size > 2 else 0.0
    at_limit = {"minimum": float(shares[0]), "maximum": float(shares[-1])}
    clipped = tuple(
        limit
        for limit, share in at_limit.items()
        if values.size > 2 and share > CLIPPING_SHARE and share >= CLIPPING_PILE_UP * interior
    )
    return Clipping(
        float(values[0]),
        float(values[-1]),
        at_limit["minimum"],
        at_limit["maximum"],
        interior,
        clipped,
    )


def diagnose_record(
    u: np.ndarray, y: np.ndarray, detrend: str, units: tuple[str, str] = ("", "")
) -> RecordDiagnostics:
    """The whole record's offsets, drift, holds and clipping, before parts or detrending.

    Args:
        u: the input as read (its unit).
        y: the output as read, one sample per input sample (its unit).
        detrend: the ``--detrend`` the fit will use: "mean", "linear" or "none".
        units: (input unit, output unit) as given, for the warnings ("" when not given).
    """
    input_trend, output_trend = trend(u), trend(y)
    drifting = input_trend.drifts or output_trend.drifts
    offset = max(input_trend.offset_share, output_trend.offset_share) > OFFSET_SHARE
    suggested = None
    if drifting and detrend != "linear":
        suggested = "linear"
    elif offset and detrend == "none":
        suggested = "mean"
    return RecordDiagnostics(
        units=tuple(units),
        detrend=detrend,
        input_trend=input_trend,
        output_trend=output_trend,
        suggested_detrend=suggested,
        input_hold=longest_hold(u),
        output_hold=longest_hold(y),
        clipping=clipping(u),
    )


def integrator_distance(estimation_samples: int) -> float:
    """How close to z = 1 a pole fitted on ``estimation_samples`` is named an integrator."""
    return max(INTEGRATOR_POLE_DISTANCE, SETTLING_TIME_CONSTANTS / estimation_samples)


def integrators(
    poles_by_order: dict[int, np.ndarray], estimation_samples: int
) -> tuple[Integrator, ...]:
    """The fitted poles within ``integrator_distance`` of z = 1, per model order.

    Args:
        poles_by_order: each fitted model's poles, by its order.
        estimation_samples: N, the length of the part they were fitted on.
    """
    threshold = integrator_distance(estimation_samples)
    return tuple(
        Integrator(order, (float(pole.real), float(pole.imag)), float(abs(1 - pole)), threshold)
        for order, poles in poles_by_order.items()
        for pole in np.asarray(poles, dtype=complex)
        if abs(1 - pole) < threshold
    )


def diagnose(
    estimation_u: np.ndarray,
    poles_by_order: dict[int, np.ndarray],
    record: RecordDiagnostics | None = None,
) -> DataDiagnostics:
    """Every diagnostic of one identification, with its warnings.

    Args:
        estimation_u: the detrended input of the estimation part.
        poles_by_order: each fitted model's poles, by its order.
        record: the whole record's diagnostics (``diagnose_record``); None to judge the parts
            alone.
    """
    excited = excitation(estimation_u, list(poles_by_order))
    found = integrators(poles_by_order, estimation_u.size)
    warnings = _warnings(excited, found, record)
    return DataDiagnostics(record, estimation_u.size, excited, found, warnings)


def _warnings(
    excited: Excitation, found: tuple[Integrator, ...], record: RecordDiagnostics | None
) -> tuple[str, ...]:
    """One sentence per diagnostic that fired."""
    warnings = []
    if excited.too_poor_for_orders:
        orders = ", ".join(str(n) for n in excited.too_poor_for_orders)
        persistence = (
            f" and only {excited.persistent_stretches} of its {excited.stretches} stretches "
            "excite them (the excitation is transient, e.g. a few pulses or steps, not "
            "persistent)"
            if excited.stretches >= 2
            and excited.persistent_stretches < PERSISTENT_SHARE * excited.stretches
            else ""
        )
        warnings.append(
            f"the input is too poor an excitation for order {orders}: it excites "
            f"{excited.order} of the {excited.tested_order} directions an order-"
            f"{excited.tested_order // EXCITATION_ORDER_PER_MODEL_ORDER} model needs"
            f"{persistence}; excite with richer, sustained signals (white noise, PRBS, multisine)"
        )
    for integrator in found:
        warnings.append(
            f"the order-{integrator.order} model has a pole at {format_pole(integrator.pole)}, "
            f"{integrator.distance_to_1:.2g} from 1: the process looks integrating; fit an "
            "integrating structure (difference the output and fit Δy(k) = y(k) - y(k-1))"
        )
    if record is None:
        return tuple(warnings)
    warnings += _record_warnings(record)
    return tuple(warnings)


def _record_warnings(record: RecordDiagnostics) -> list[str]:
    """The whole record's warnings: drift or offset, holds, clipping."""
    warnings = []
    signals = (
        ("input", record.input_trend, record.input_hold, record.units[0]),
        ("output", record.output_trend, record.output_hold, record.units[1]),
    )
    if record.suggested_detrend is not None:
        drift = record.suggested_detrend == "linear"
        found = "; ".join(
            f"the {name} {'drifts' if drift else 'has an offset'}: "
            + (
                f"a straight line carries {t.drift_share:.0%} of its variance "
                f"(slope {_with_unit(t.slope_per_sample, unit, '.3g')} per sample)"
                if drift
                else f"a constant {_with_unit(t.mean, unit)} carries {t.offset_share:.0%} of "
                "its mean square"
            )
            for name, t, _, unit in signals
            if (t.drifts if drift else t.offset_share > OFFSET_SHARE)
        )
        warnings.append(
            f"{found}, which --detrend {record.detrend} leaves in: use --detrend "
            f"{record.suggested_detrend} (suggested, not applied: the choice changes the "
            "operating point the model file holds, and a ramp may be the input's doing)"
        )
    for (name, _, hold, unit), limit in zip(
        signals, (STUCK_INPUT_SHARE, STUCK_OUTPUT_SHARE), strict=True
    ):
        if hold.share > limit:
            warnings.append(
                f"the {name} is stuck at {_with_unit(hold.value, unit)} for {hold.samples} "
                f"samples ({hold.share:.0%} of the record) from sample {hold.start}"
            )
    clip = record.clipping
    for limit in clip.clipped_at:
        value, share = (
            (clip.minimum, clip.share_at_minimum)
            if limit == "minimum"
            else (clip.maximum, clip.share_at_maximum)
        )
        warnings.append(
            f"the input is clipped at its {limit} {_with_unit(value, record.units[0])}: "
            f"{share:.1%} of its samples sit there, where the record says nothing of the "
            "response to inputs beyond it"
        )
    return warnings


def _with_unit(value: float, unit: str, spec: str = ".9g") -> str:
    """``value`` with its unit as given (none when not given)."""
    return f"{value:{spec}} {unit}" if unit else f"{value:{spec}}"
