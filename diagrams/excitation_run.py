"""Exciting the plant open loop for identification: the request, the run and its summary.

The inlet valve (outlet shut) follows the paper's uniform white noise (Eq. 22-23), a PRBS or a
Schroeder multisine about an offset current, clipped to the valve's [0, saturation] range as the
authors clipped theirs, while the cameras, their local Kalman filters and the fusion watch the
head. The recording has the topics of a closed-loop run (the command topic carries the
excitation), so `maskless identify` reads it as it is.
"""

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from maskless.analysis.metrics import estimate_error_std_m
from maskless.diagrams.closed_loop import ClosedLoop, LoopDrive, add_plant, assemble_loop
from maskless.diagrams.controller_design import NominalPneumatic
from maskless.diagrams.output_folder import RunFolder
from maskless.diagrams.request_labels import LabelledRequest
from maskless.diagrams.run_summary import estimation_start_s
from maskless.diagrams.scenario import PneumaticPlant, Scenario, kind_name
from maskless.diagrams.scenario_plant import inlet_current_range_a
from maskless.diagrams.simulation import RUN_FILES, SimulationRun, simulate_loop
from maskless.errors import ConfigError
from maskless.systems.control.excitation import (
    ExcitationSignal,
    add_excitation_source,
    clip_to_valve_range,
    clipped_fraction,
    excitation_signal,
    sample_count,
    theoretical_uniform_std,
    validated_band,
)
from maskless.systems.limits import DURATION_S, SAMPLE_PERIOD_S
from maskless.systems.units import a_to_ma, m_to_mm

SIGNALS = ("uniform", "prbs", "multisine")


@dataclass(frozen=True)
class ExcitationRequest(LabelledRequest):
    """An identification experiment; checked when made.

    Attributes:
        signal: "uniform" (the paper's, Eq. 22-23), "prbs" or "multisine" (Schroeder phases).
        amplitude_a: half-width of the current excursion (A).
        offset_a: the centre current (A); None for mid-way between the inlet's starting and
            saturation currents.
        duration_s: the experiment's length (s).
        sample_period_s: the excitation's and the recording's period (s); None for the
            controller's.
        clock_periods: prbs only: samples each bit is held.
        band_hz: multisine only: (low, high) band in Hz; None for the whole grid up to Nyquist.
        labels: see ``LabelledRequest``.
    """

    signal: str = "uniform"
    amplitude_a: float = 0.050
    offset_a: float | None = None
    duration_s: float = 600.0
    sample_period_s: float | None = None
    clock_periods: int = 1
    band_hz: tuple[float, float] | None = None

    def __post_init__(self):
        """Raises ConfigError for the first field out of range, named as the user named it."""

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
        require(positive_current, "amplitude_a", "a positive current")
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


@dataclass
class ExcitationRun:
    """The outcome of ``excite``.

    Attributes:
        run: the simulated experiment: its signals, recording and plot (``write_mcap``,
            ``plot(path, show_tolerance=False)``).
        designed: the excitation as designed (A).
        applied: the excitation clipped to the inlet's range, as applied (A).
        summary: the signal's statistics (mA) and what the head and fused estimate did (mm).
    """

    run: SimulationRun
    designed: ExcitationSignal
    applied: ExcitationSignal
    summary: dict


def excite(scenario: Scenario, request: ExcitationRequest) -> ExcitationRun:
    """Designs the excitation ``request`` asks for, checks it, and runs it on the plant open loop.

    The plant is ``scenario``'s; the run lasts ``request.duration_s`` (the scenario's own duration
    is not used).

    Raises:
        ConfigError: fewer than two samples, a PRBS with fewer than two bits, a multisine band
            with no line of the frequency grid, or an excitation that clipping to the inlet's
            range leaves constant.
    """
    return _plan_experiment(scenario, request).run()


@dataclass(frozen=True)
class _Experiment:
    """An excitation designed and checked, not yet run (``excite``'s two halves)."""

    scenario: Scenario
    designed: ExcitationSignal
    applied: ExcitationSignal
    amplitude_a: float
    offset_a: float
    valve_range_a: tuple[float, float]

    def run(self) -> ExcitationRun:
        """Simulates the experiment and summarises it."""
        run = simulate_loop(build_excitation_loop(self.scenario, self.applied), self.scenario)
        summary = excitation_summary(
            self.designed, self.applied, self.amplitude_a, self.offset_a, self.valve_range_a, run
        )
        return ExcitationRun(run, self.designed, self.applied, summary)


def _plan_experiment(scenario: Scenario, request: ExcitationRequest) -> _Experiment:
    """The experiment ``request`` asks for, designed and checked (raises as ``excite``)."""
    start_a, saturation_a = inlet_current_range_a(scenario)
    valve_range_a = (0.0, saturation_a)
    offset_a = 0.5 * (start_a + saturation_a) if request.offset_a is None else request.offset_a
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
    designed, applied = design_excitation(
        request.signal,
        request.amplitude_a,
        offset_a,
        request.duration_s,
        period_s,
        scenario.random_seed,
        valve_range_a,
        clock_periods=request.clock_periods,
        band_hz=request.band_hz,
        band_label=request.label("band_hz"),
    )
    if np.ptp(applied.values) == 0.0:
        raise ConfigError(
            f"offset {a_to_ma(offset_a):g} mA ± amplitude {a_to_ma(request.amplitude_a):g} mA: "
            f"clipped to the inlet's [{a_to_ma(valve_range_a[0]):g}, "
            f"{a_to_ma(valve_range_a[1]):g}] mA nothing of the excitation is left"
        )
    experiment = dataclasses.replace(scenario, duration_s=request.duration_s)
    return _Experiment(experiment, designed, applied, request.amplitude_a, offset_a, valve_range_a)


def excite_to_files(
    scenario: Scenario, request: ExcitationRequest, out: str | Path, *, overwrite: bool = False
) -> dict:
    """``excite``, writing OUT/run.mcap and OUT/run.png (``maskless excite``).

    With rendered cameras, the recording holds their images and OUT/frames.png shows each
    camera's first and last one. Returns the summary with the files written (``files``).

    The request is checked, then OUT claimed as ``simulate_to_files`` claims it (refused when in
    use or, unless ``overwrite``, holding a run), both before anything is simulated; the files
    are written under temporary names and renamed when all are written.

    Raises:
        ConfigError: as ``excite``, or OUT refused.
    """
    experiment = _plan_experiment(scenario, request)
    with RunFolder(out, RUN_FILES, overwrite=overwrite) as folder:
        excited = experiment.run()
        excited.run.write_mcap(folder.temporary("run.mcap"))
        excited.run.plot(folder.temporary("run.png"), show_tolerance=False)
        files = {"recording": "run.mcap", "plot": "run.png"}
        if excited.run.frames:
            excited.run.plot_frames(folder.temporary("frames.png"))
            files["frames"] = "frames.png"
    return {**excited.summary, "files": folder.final_paths(files)}


def build_excitation_loop(
    config: Scenario, signal: ExcitationSignal, record: bool = True
) -> ClosedLoop:
    """The plant driven open loop by ``signal`` on its inlet (outlet shut), the head watched.

    The cameras, local filters and fusion watch the head; outputs and logs are as
    ``build_closed_loop``'s, logged at the signal's sample period. ``controller`` is "excitation",
    and model and design are None.
    """
    builder = DiagramBuilder()
    nominal = NominalPneumatic.of(config) if isinstance(config.plant, PneumaticPlant) else None
    plant = add_plant(builder, config, nominal)
    inlet = add_excitation_source(builder, signal, name="excitation")
    outlet = builder.AddNamedSystem("outlet_valve_shut", ConstantVectorSource([0.0]))
    resting = builder.AddNamedSystem("reference", ConstantVectorSource([plant.start_height_m]))
    drive = LoopDrive(
        inlet,
        outlet.get_output_port(),
        resting.get_output_port(),
        signal.sample_period_s,
        "excitation",
    )
    return assemble_loop(
        builder, config, plant, drive, record, f"{kind_name(config.plant)}_excitation"
    )


def design_excitation(
    kind: str,
    amplitude_a: float,
    offset_a: float,
    duration_s: float,
    sample_period_s: float,
    seed: int,
    valve_range_a: tuple[float, float],
    clock_periods: int = 1,
    band_hz: tuple[float, float] | None = None,
    band_label: str = "band_hz",
) -> tuple[ExcitationSignal, ExcitationSignal]:
    """(designed, clipped to ``valve_range_a``) excitation of the named kind."""
    options = {}
    if kind == "prbs":
        options["clock_periods"] = clock_periods
    if kind == "multisine" and band_hz is not None:
        nyquist_hz = 0.5 / sample_period_s
        try:
            validated_band(band_hz, nyquist_hz)
        except ValueError:  # said again in the request's terms
            raise ConfigError(
                f"{band_label} {band_hz[0]:g}:{band_hz[1]:g}: expected 0 < LOW <= HIGH < the "
                f"Nyquist frequency, {nyquist_hz:g} Hz"
            ) from None
        options["frequency_band_hz"] = band_hz
    designed = excitation_signal(
        kind,
        amplitude=amplitude_a,
        duration_s=duration_s,
        sample_period_s=sample_period_s,
        seed=seed,
        offset=offset_a,
        **options,
    )
    return designed, clip_to_valve_range(designed, *valve_range_a)


def excitation_summary(
    designed: ExcitationSignal,
    applied: ExcitationSignal,
    amplitude_a: float,
    offset_a: float,
    valve_range_a: tuple[float, float],
    run: SimulationRun,
) -> dict:
    """The signal's statistics (mA) and what the head and fused estimate did (mm)."""
    times_s, head = run.signals["head_height_m"].times_s, run.signals["head_height_m"].values[0]
    fused = run.signals["fusion.estimated_state"].values[0]
    start_s = estimation_start_s(run.scenario, times_s)
    summary = {
        "plant": run.closed_loop.plant,
        "signal": designed.kind,
        "samples": applied.num_samples,
        "sample_period_s": applied.sample_period_s,
        "amplitude_ma": a_to_ma(amplitude_a),
        "offset_ma": a_to_ma(offset_a),
        "mean_ma": a_to_ma(float(np.mean(designed.values))),
        "std_ma": a_to_ma(designed.std()),
        "crest_factor": designed.crest_factor(),
        "clipped_fraction": clipped_fraction(designed, *valve_range_a),
        "applied_std_ma": a_to_ma(applied.std()),
        "applied_crest_factor": applied.crest_factor(),
        "head_height_mm": {"min": m_to_mm(float(head.min())), "max": m_to_mm(float(head.max()))},
        "fused_error_std_mm": m_to_mm(estimate_error_std_m(times_s, fused, head, start_s)),
        "estimation_start_s": start_s,
        "wall_time_s": run.wall_time_s,
    }
    if designed.kind == "uniform":
        summary["uniform_theoretical_std_ma"] = a_to_ma(theoretical_uniform_std(amplitude_a))
    return summary


def format_excitation_summary(summary: dict) -> str:
    """The summary as text a person reads."""
    lines = [
        f"maskless excite: {summary['signal']} on the {summary['plant']} plant's inlet, "
        f"{summary['samples']} samples at {summary['sample_period_s']:.4g} s",
        f"  offset {summary['offset_ma']:.1f} mA, amplitude {summary['amplitude_ma']:.1f} mA, "
        f"mean {summary['mean_ma']:.1f} mA",
        f"  std {summary['std_ma']:.2f} mA"
        + (
            f" (A/sqrt(3) = {summary['uniform_theoretical_std_ma']:.2f} mA, Eq. 23)"
            if "uniform_theoretical_std_ma" in summary
            else ""
        ),
        f"  crest factor {summary['crest_factor']:.3f} designed, "
        f"{summary['applied_crest_factor']:.3f} after clipping "
        f"({100 * summary['clipped_fraction']:.1f} % of samples clipped)",
        f"  head height {summary['head_height_mm']['min']:.2f}-"
        f"{summary['head_height_mm']['max']:.2f} mm; fused estimate error std (from "
        f"t = {summary['estimation_start_s']:g} s) "
        f"{summary['fused_error_std_mm']:.3f} mm",
        f"  wall time {summary['wall_time_s']:.2f} s",
        "Files:",
    ]
    lines += [f"  {name}: {path}" for name, path in summary["files"].items()]
    return "\n".join(lines)
