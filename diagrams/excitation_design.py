"""The excitation experiment a request asks for: its signals designed, each valve's currents.

The request names the signal (``systems.control.excitation``) and which valves it drives
(``systems.control.valve_pair_excitation``); :func:`plan_excitation` resolves its defaults against
the scenario's valves, designs the signals, clips each valve's current to that valve's range and
refuses an experiment clipping leaves nothing of. ``diagrams.excitation_run`` runs the plan.
"""

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from maskless.diagrams.request_labels import LabelledRequest
from maskless.diagrams.scenario import PneumaticPlant, Scenario
from maskless.diagrams.scenario_plant import inlet_current_range_a
from maskless.errors import ConfigError
from maskless.systems.control.excitation import (
    MULTILEVEL_HOLD_S,
    MULTILEVEL_LEVELS,
    ExcitationSignal,
    clip_to_valve_range,
    clipped_fraction,
    excitation_signal,
    hold_samples,
    sample_count,
    sampled_signal,
    validated_band,
)
from maskless.systems.control.valve_allocation import current_split_allocation
from maskless.systems.control.valve_level_design import TOP_CURRENT_A, random_level_currents
from maskless.systems.control.valve_pair_excitation import (
    VALVE_DRIVES,
    outlet_seed,
    split_range_clipped_fractions,
    split_range_currents,
)
from maskless.systems.limits import DURATION_S, SAMPLE_PERIOD_S
from maskless.systems.plant.pneumatic_physics import ValveParameters
from maskless.systems.units import a_to_ma

SIGNALS = ("uniform", "prbs", "multisine", "multilevel", "valve-levels", "designed-levels")
# The signals whose levels are held for --hold's random times.
HELD_LEVEL_SIGNALS = ("multilevel", "valve-levels", "designed-levels")
# The signals that drive both valves through levels from shut to TOP_CURRENT_A.
VALVE_LEVEL_SIGNALS = ("valve-levels", "designed-levels")
# designed-levels' random holds unless asked otherwise: the design issue 14 measured
# (``valve_level_experiment.SequentialDesign``) had its random levels held 5-60 s.
DESIGNED_LEVELS_HOLD_S = (5.0, 60.0)

# The half-width of an excitation whose request gives none (multilevel aside): `maskless excite`'s
# long-standing 50 mA.
DEFAULT_AMPLITUDE_A = 0.050


@dataclass(frozen=True)
class ExcitationRequest(LabelledRequest):
    """An identification experiment; checked when made.

    Attributes:
        signal: "uniform" (the paper's, Eq. 22-23), "prbs", "multisine" (Schroeder phases) or
            "multilevel" (random levels held for random times, to see the valves' static curve),
            or "valve-levels" (both valves, continuous stratified levels from shut to
            ``valve_level_design.TOP_CURRENT_A``, the design benchmarks/hammerstein.py measures
            the Hammerstein fit on; split-range: one valve at a time), or "designed-levels"
            (those levels, split-range, with a stretch designed as the run goes from what the
            record before it shows: ``valve_level_experiment.run_designed_experiment``).
        amplitude_a: half-width of the current excursion (A); None for 50 mA, or for a
            multilevel signal half the valve's whole range [0, saturation], so that its levels
            span it.
        offset_a: the centre current (A); None for mid-way between the valve's starting and
            saturation currents, or for a multilevel signal the centre of its whole range.
        duration_s: the experiment's length (s).
        sample_period_s: the excitation's and the recording's period (s); None for the
            controller's.
        clock_periods: prbs only: samples each bit is held.
        band_hz: multisine only: (low, high) band in Hz; None for the whole grid up to Nyquist.
        valve_drive: "inlet" (the outlet shut), "independent" (each valve its own signal about
            its own centre, clipped to its own range) or "split-range" (one command in
            inlet-equivalent amperes split between the valves as the controller splits its
            command: its range runs from one inlet span below the inlet's starting current, the
            outlet fully open, to the inlet's saturation, and its centre is the split point).
        levels: multilevel only: the number of levels.
        hold_s: multilevel, valve-levels and designed-levels: (shortest, longest) time a random
            level is held (s); None for ``DESIGNED_LEVELS_HOLD_S`` with designed-levels, else
            ``MULTILEVEL_HOLD_S``. Designed-levels' targeted holds last the shortest, or the
            design's own hold if longer (``excitation_run.sequential_design``).
        labels: see ``LabelledRequest``.
    """

    signal: str = "uniform"
    amplitude_a: float | None = None
    offset_a: float | None = None
    duration_s: float = 600.0
    sample_period_s: float | None = None
    clock_periods: int = 1
    band_hz: tuple[float, float] | None = None
    valve_drive: str = "inlet"
    levels: int = MULTILEVEL_LEVELS
    hold_s: tuple[float, float] | None = None

    def __post_init__(self):
        """Raises ConfigError for the first field out of range, named as the user named it."""
        if self.hold_s is None:
            designed = self.signal == "designed-levels"
            default = DESIGNED_LEVELS_HOLD_S if designed else MULTILEVEL_HOLD_S
            object.__setattr__(self, "hold_s", default)

        def require(condition, field_name, expected):
            if not condition:
                value = getattr(self, field_name)
                raise ConfigError(f"{self.label(field_name)} {value!r}: expected {expected}")

        def finite(value):
            return isinstance(value, int | float) and math.isfinite(value)

        require(self.signal in SIGNALS, "signal", f"one of {', '.join(SIGNALS)}")
        require(
            finite(self.duration_s) and self.duration_s > 0,
            "duration_s",
            "a positive number of seconds",
        )
        require(DURATION_S.contains(self.duration_s), "duration_s", DURATION_S.expected())
        positive_current = finite(self.amplitude_a) and self.amplitude_a > 0
        require(self.amplitude_a is None or positive_current, "amplitude_a", "a positive current")
        require(self.offset_a is None or finite(self.offset_a), "offset_a", "a finite current")
        require(
            self.sample_period_s is None
            or (finite(self.sample_period_s) and self.sample_period_s > 0),
            "sample_period_s",
            "a positive sample period in s",
        )
        require(
            self.sample_period_s is None or SAMPLE_PERIOD_S.contains(self.sample_period_s),
            "sample_period_s",
            SAMPLE_PERIOD_S.expected(),
        )
        require(
            isinstance(self.clock_periods, int) and self.clock_periods >= 1,
            "clock_periods",
            "1 or more samples per bit",
        )
        require(
            self.valve_drive in VALVE_DRIVES, "valve_drive", f"one of {', '.join(VALVE_DRIVES)}"
        )
        # A Schroeder multisine ignores its seed: both valves would follow one signal, and a fit
        # could not tell their effects apart.
        require(
            not (self.valve_drive == "independent" and self.signal == "multisine"),
            "valve_drive",
            "inlet or split-range with a multisine (its phases ignore the seed, so independent "
            "valves would get the same signal); or an independent drive with uniform, prbs or "
            "multilevel",
        )
        require(
            isinstance(self.levels, int) and not isinstance(self.levels, bool) and self.levels >= 2,
            "levels",
            "2 or more levels",
        )
        if self.signal == "valve-levels":
            require(
                self.valve_drive in ("split-range", "independent"),
                "valve_drive",
                "split-range or independent with valve-levels (it drives both valves)",
            )
        if self.signal == "designed-levels":
            require(
                self.valve_drive == "split-range",
                "valve_drive",
                "split-range with designed-levels (the design measured, one valve at a time)",
            )
        if self.signal in VALVE_LEVEL_SIGNALS:
            for field_name in ("amplitude_a", "offset_a"):
                require(
                    getattr(self, field_name) is None,
                    field_name,
                    f"none with {self.signal} (its levels span each valve from shut to "
                    f"{a_to_ma(TOP_CURRENT_A):g} mA)",
                )
        hold_pair = isinstance(self.hold_s, tuple | list) and len(self.hold_s) == 2
        require(
            hold_pair
            and all(finite(h) for h in self.hold_s)
            and 0 < self.hold_s[0] <= self.hold_s[1],
            "hold_s",
            "SHORTEST:LONGEST seconds with 0 < SHORTEST <= LONGEST",
        )


@dataclass(frozen=True)
class ExcitationPlan:
    """An excitation designed and checked, not yet run.

    Attributes:
        scenario: the scenario, lasting the experiment's duration.
        request: what was asked for.
        designed: the inlet's signal as designed, or the split-range command (A).
        inlet: the inlet's current as applied (A).
        outlet: the outlet's current as applied (A); None when it stays shut.
        designed_outlet: the outlet's own signal as designed (A), in an independent drive.
        amplitude_a, offset_a: the half-width and centre ``designed`` was designed with (A).
        designed_range_a: what ``designed`` was clipped to: the inlet's [0, saturation], or the
            split-range command's range (A).
        clipped: each valve's fraction of samples clipped ("inlet", "outlet").
    """

    scenario: Scenario
    request: ExcitationRequest
    designed: ExcitationSignal
    inlet: ExcitationSignal
    outlet: ExcitationSignal | None
    designed_outlet: ExcitationSignal | None
    amplitude_a: float
    offset_a: float
    designed_range_a: tuple[float, float]
    clipped: dict[str, float]


def valve_current_ranges_a(scenario: Scenario) -> dict[str, tuple[float, float]]:
    """Each valve's (starting, saturation) currents (A).

    The pneumatic plant's own valves; in front of a linear model, the paper's valve at both.
    """
    if isinstance(scenario.plant, PneumaticPlant):
        outlet = scenario.pneumatic.outlet
        outlet_range_a = (outlet.starting_current_a, outlet.saturation_current_a)
    else:
        outlet_range_a = inlet_current_range_a(scenario)
    return {"inlet": inlet_current_range_a(scenario), "outlet": outlet_range_a}


def _centre_and_half_width(
    request: ExcitationRequest, working_a: tuple[float, float], whole_a: tuple[float, float]
) -> tuple[float, float]:
    """(offset, amplitude) (A): the request's, or the defaults its docstring states.

    ``working_a`` is where the drive moves air, ``whole_a`` all it can be commanded.
    """
    span_a = whole_a if request.signal == "multilevel" else working_a
    offset_a = 0.5 * (span_a[0] + span_a[1]) if request.offset_a is None else request.offset_a
    if request.amplitude_a is not None:
        return offset_a, request.amplitude_a
    if request.signal == "multilevel":
        return offset_a, 0.5 * (whole_a[1] - whole_a[0])
    return offset_a, DEFAULT_AMPLITUDE_A


def plan_excitation(scenario: Scenario, request: ExcitationRequest) -> ExcitationPlan:
    """The experiment ``request`` asks for, designed and checked (raises as ``excite``)."""
    period_s = request.sample_period_s or scenario.offset_free_lqg.sample_period_s
    samples = sample_count(request.duration_s, period_s)
    if samples < 2:
        raise ConfigError(
            f"{request.label('duration_s')} {request.duration_s}: expected at least two samples "
            f"of {period_s:.6g} s"
        )
    if request.signal == "prbs" and not request.clock_periods <= samples // 2:
        raise ConfigError(
            f"{request.label('clock_periods')} {request.clock_periods}: expected 1 to "
            f"{samples // 2} (half the {samples} samples), so the PRBS has at least two bits"
        )
    if request.signal in VALVE_LEVEL_SIGNALS:
        return _plan_valve_levels(scenario, request, period_s, samples)
    ranges_a = valve_current_ranges_a(scenario)
    seed = scenario.random_seed
    if request.valve_drive == "split-range":
        inlet_valve, outlet_valve = (
            ValveParameters(starting_current_a=start_a, saturation_current_a=saturation_a)
            for start_a, saturation_a in (ranges_a["inlet"], ranges_a["outlet"])
        )
        allocation = current_split_allocation(inlet_valve, outlet_valve)
        command_range_a = allocation.command_range
        offset_a, amplitude_a = _centre_and_half_width(request, command_range_a, command_range_a)
        designed = design_excitation(request, period_s, amplitude_a, offset_a, seed)
        # The split clips the command to its range (each valve held at its end beyond it), so
        # it is the one clip: nothing is left when neither valve's current moves.
        inlet, outlet = split_range_currents(designed, allocation)
        _require_some_left(
            max(np.ptp(inlet.values), np.ptp(outlet.values)) > 0.0,
            "the split-range command's",
            command_range_a,
            offset_a,
            amplitude_a,
        )
        fractions = split_range_clipped_fractions(designed, allocation)
        return ExcitationPlan(
            dataclasses.replace(scenario, duration_s=request.duration_s),
            request,
            designed,
            inlet,
            outlet,
            None,
            amplitude_a,
            offset_a,
            command_range_a,
            dict(zip(("inlet", "outlet"), fractions, strict=True)),
        )
    designs, applied, clipped = {}, {}, {"outlet": 0.0}
    valves = ("inlet", "outlet") if request.valve_drive == "independent" else ("inlet",)
    for valve in valves:
        whole_range_a = (0.0, ranges_a[valve][1])
        offset_a, amplitude_a = _centre_and_half_width(request, ranges_a[valve], whole_range_a)
        # The outlet's signal must not correlate with the inlet's (valve_pair_excitation): a
        # PRBS starts half its period later, a random design draws from a seed of its own.
        shifted = valve == "outlet" and request.signal == "prbs"
        valve_seed = outlet_seed(seed) if valve == "outlet" and not shifted else seed
        designed = design_excitation(
            request, period_s, amplitude_a, offset_a, valve_seed, half_period_shift=shifted
        )
        applied[valve] = clip_to_valve_range(designed, *whole_range_a)
        _require_some_left(
            np.ptp(applied[valve].values) > 0.0,
            f"the {valve}'s",
            whole_range_a,
            offset_a,
            amplitude_a,
        )
        designs[valve] = (designed, offset_a, amplitude_a, whole_range_a)
        clipped[valve] = clipped_fraction(designed, *whole_range_a)
    designed, offset_a, amplitude_a, inlet_range_a = designs["inlet"]
    return ExcitationPlan(
        dataclasses.replace(scenario, duration_s=request.duration_s),
        request,
        designed,
        applied["inlet"],
        applied.get("outlet"),
        designs["outlet"][0] if "outlet" in designs else None,
        amplitude_a,
        offset_a,
        inlet_range_a,
        clipped,
    )


def _plan_valve_levels(
    scenario: Scenario, request: ExcitationRequest, period_s: float, samples: int
) -> ExcitationPlan:
    """Both valves' levels (``valve_level_design.random_level_currents``), applied as designed.

    The levels run from shut to ``TOP_CURRENT_A``, past saturation, where each valve is fully open
    whatever its current: nothing is clipped. A designed-levels run replaces a stretch of them as
    it goes (``excitation_run``).
    """
    _check_holds(request, period_s)
    arrangement = "split_range" if request.valve_drive == "split-range" else "independent"
    currents = random_level_currents(
        samples,
        period_s,
        (TOP_CURRENT_A, TOP_CURRENT_A),
        request.hold_s,
        scenario.random_seed,
        arrangement,
    )
    inlet, outlet = (sampled_signal(row, period_s, request.signal) for row in currents)
    return ExcitationPlan(
        scenario=dataclasses.replace(scenario, duration_s=request.duration_s),
        request=request,
        designed=inlet,
        inlet=inlet,
        outlet=outlet,
        designed_outlet=outlet,
        amplitude_a=0.5 * TOP_CURRENT_A,
        offset_a=0.5 * TOP_CURRENT_A,
        designed_range_a=(0.0, TOP_CURRENT_A),
        clipped={"inlet": 0.0, "outlet": 0.0},
    )


def _check_holds(request: ExcitationRequest, sample_period_s: float) -> None:
    """Raises ConfigError, naming ``hold_s`` as the user did, for holds no sample can make."""
    try:
        hold_samples(request.hold_s, sample_period_s)
    except ValueError:  # said again in the request's terms
        raise ConfigError(
            f"{request.label('hold_s')} {request.hold_s[0]:g}:{request.hold_s[1]:g}: "
            f"expected holds of at least one sample, {sample_period_s:.6g} s, with a whole "
            "sample from SHORTEST to LONGEST"
        ) from None


def _require_some_left(
    moving: bool,
    whose: str,
    range_a: tuple[float, float],
    offset_a: float,
    amplitude_a: float,
) -> None:
    """Raises ConfigError unless some current still ``moving`` after clipping to ``range_a``."""
    if not moving:
        raise ConfigError(
            f"offset {a_to_ma(offset_a):g} mA ± amplitude {a_to_ma(amplitude_a):g} mA: "
            f"clipped to {whose} [{a_to_ma(range_a[0]):g}, {a_to_ma(range_a[1]):g}] mA nothing "
            "of the excitation is left"
        )


def design_excitation(
    request: ExcitationRequest,
    sample_period_s: float,
    amplitude_a: float,
    offset_a: float,
    seed: int,
    half_period_shift: bool = False,
) -> ExcitationSignal:
    """The excitation ``request`` asks for, about ``offset_a`` +- ``amplitude_a``, not clipped.

    Args:
        request: the signal's kind and its kind's own settings.
        sample_period_s: the signal's sample period (s).
        amplitude_a: half-width of the excursion (A).
        offset_a: its centre (A).
        seed: the design's seed.
        half_period_shift: prbs only: start the sequence half its period later.
    """
    options = {}
    if request.signal == "prbs":
        options["clock_periods"] = request.clock_periods
        options["half_period_shift"] = half_period_shift
    if request.signal == "multilevel":
        _check_holds(request, sample_period_s)
        options["num_levels"] = request.levels
        options["hold_s"] = request.hold_s
    if request.signal == "multisine" and request.band_hz is not None:
        band_hz = request.band_hz
        nyquist_hz = 0.5 / sample_period_s
        try:
            validated_band(band_hz, nyquist_hz)
        except ValueError:  # said again in the request's terms
            raise ConfigError(
                f"{request.label('band_hz')} {band_hz[0]:g}:{band_hz[1]:g}: expected 0 < LOW "
                f"<= HIGH < the Nyquist frequency, {nyquist_hz:g} Hz"
            ) from None
        options["frequency_band_hz"] = band_hz
    return excitation_signal(
        request.signal,
        amplitude=amplitude_a,
        duration_s=request.duration_s,
        sample_period_s=sample_period_s,
        seed=seed,
        offset=offset_a,
        **options,
    )
