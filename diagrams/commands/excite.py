"""Excite the plant open loop for identification: record it to MCAP, plot it and summarise it.

Drives the inlet valve (outlet shut) with the paper's uniform white noise (Eq. 22-23), a PRBS or a
Schroeder multisine about an offset current, clipped to the valve's [0, saturation] range as the
authors clipped theirs, while both cameras, their local Kalman filters and the fusion watch the
head. Writes DIR/run.mcap with the topics `maskless simulate` writes (the command topic carries the
excitation; the reference topic holds the resting height, as nothing is commanded), DIR/run.png,
and prints the signal's standard deviation (against A/sqrt(3) for uniform noise), its crest factor
and how much of it was clipped. `maskless identify --input DIR/run.mcap --ts PERIOD` then fits a
model to the recording.
"""

import argparse
import json
import math
from pathlib import Path

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from maskless.analysis.metrics import estimate_error_std_m
from maskless.analysis.summary import estimation_start_s
from maskless.diagrams.cli import add_config_argument
from maskless.diagrams.closed_loop import (
    ClosedLoop,
    LoopDrive,
    NominalPneumatic,
    add_plant,
    assemble_loop,
    inlet_current_range_a,
)
from maskless.diagrams.commands.simulate import SimulationRun, plot_run, simulate_loop
from maskless.diagrams.run_recording import recording_channels
from maskless.diagrams.scenario import SimulationConfig, load_config_with_overrides
from maskless.errors import ConfigError
from maskless.recording import write_recording
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
from maskless.systems.units import a_to_ma, m_to_mm, ma_to_a

USER_ERRORS = (ConfigError, FileNotFoundError, ValueError)

SIGNALS = ("uniform", "prbs", "multisine")


def build_excitation_loop(
    config: SimulationConfig, signal: ExcitationSignal, record: bool = True
) -> ClosedLoop:
    """The plant driven open loop by ``signal`` on its inlet (outlet shut), watched by the
    cameras, local filters and fusion; outputs and logs as ``build_closed_loop``'s, logged at the
    signal's sample period. ``controller`` is "excitation", and model and design are None."""
    builder = DiagramBuilder()
    nominal = NominalPneumatic.of(config) if config.plant == "pneumatic" else None
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
        builder, config, plant, drive, record, f"{config.plant.split(':')[0]}_excitation"
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
) -> tuple[ExcitationSignal, ExcitationSignal]:
    """(designed, clipped to ``valve_range_a``) excitation of the named kind."""
    if kind not in SIGNALS:
        raise ValueError(f"--signal {kind!r}: expected one of {', '.join(SIGNALS)}")
    options = {}
    if kind == "prbs":
        options["clock_periods"] = clock_periods
    if kind == "multisine" and band_hz is not None:
        nyquist_hz = 0.5 / sample_period_s
        try:
            validated_band(band_hz, nyquist_hz)
        except ValueError:  # said again in the flag's terms
            raise ValueError(
                f"--band {band_hz[0]:g}:{band_hz[1]:g}: expected 0 < LOW <= HIGH < the Nyquist "
                f"frequency, {nyquist_hz:g} Hz"
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
    start_s = estimation_start_s(run.config, times_s)
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


def _band(text: str) -> tuple[float, float]:
    try:
        low, high = (float(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected LOW:HIGH in Hz, e.g. 0.01:1"
        ) from None
    return low, high


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless excite`."""
    parser.add_argument("--signal", choices=SIGNALS, default="uniform", help="default uniform")
    parser.add_argument(
        "--amplitude",
        type=float,
        default=50.0,
        metavar="MA",
        help="half-width of the current excursion, mA (default 50)",
    )
    parser.add_argument(
        "--offset",
        type=float,
        default=None,
        metavar="MA",
        help="centre current, mA (default: mid-way between the inlet's starting and saturation "
        "currents)",
    )
    parser.add_argument(
        "--duration", type=float, default=600.0, metavar="S", help="seconds (default 600)"
    )
    parser.add_argument(
        "--period",
        type=float,
        default=None,
        metavar="S",
        help="sample period of the excitation and the recording, s (default: the controller's, "
        "1/15 s)",
    )
    parser.add_argument(
        "--clock-periods",
        type=int,
        default=1,
        metavar="N",
        help="prbs: samples each bit is held (default 1)",
    )
    parser.add_argument(
        "--band",
        type=_band,
        default=None,
        metavar="LOW:HIGH",
        help="multisine: frequency band in Hz (default: the whole grid up to Nyquist)",
    )
    parser.add_argument("--seed", type=int, default=None, metavar="N", help="default: the config's")
    parser.add_argument(
        "--plant",
        default=None,
        metavar="PLANT",
        help="pneumatic, paper or identified:MODEL.yaml (default: the config's, pneumatic)",
    )
    add_config_argument(parser)
    parser.add_argument(
        "--out", type=Path, default=Path("excitation"), metavar="DIR", help="default ./excitation"
    )
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")


def _require(condition: bool, flag: str, value, expected: str) -> None:
    if not condition:
        raise ValueError(f"{flag} {value}: expected {expected}")


def run_excitation(args: argparse.Namespace) -> dict:
    """Designs, runs and records the experiment ``args`` describe; returns the summary. Every
    flag is checked before anything is simulated."""
    _require(
        math.isfinite(args.duration) and args.duration > 0, "--duration", args.duration,
        "a positive number of seconds",
    )  # fmt: skip
    _require(
        math.isfinite(args.amplitude) and args.amplitude > 0, "--amplitude", args.amplitude,
        "a positive current in mA",
    )  # fmt: skip
    if args.offset is not None:
        _require(math.isfinite(args.offset), "--offset", args.offset, "a current in mA")
    if args.period is not None:
        _require(
            math.isfinite(args.period) and args.period > 0, "--period", args.period,
            "a positive sample period in s",
        )  # fmt: skip
    config = load_config_with_overrides(
        args.config,
        {
            "--seed": ("random_seed", args.seed),
            "--plant": ("plant", args.plant),
            "--duration": ("duration_s", args.duration),
        },
    )
    valve_range_a = (0.0, inlet_current_range_a(config)[1])
    offset_a = 0.5 * sum(inlet_current_range_a(config)) if args.offset is None else ma_to_a(
        args.offset
    )
    period_s = config.offset_free_lqg.sample_period_s if args.period is None else args.period
    samples = sample_count(args.duration, period_s)
    _require(
        1 <= args.clock_periods <= samples // 2, "--clock-periods", args.clock_periods,
        f"1 to {samples // 2} (half the {samples} samples), so the PRBS has at least two bits",
    )  # fmt: skip
    designed, applied = design_excitation(
        args.signal,
        ma_to_a(args.amplitude),
        offset_a,
        args.duration,
        period_s,
        config.random_seed,
        valve_range_a,
        clock_periods=args.clock_periods,
        band_hz=args.band,
    )
    if np.ptp(applied.values) == 0.0:
        raise ValueError(
            f"--offset {a_to_ma(offset_a):g} mA ± --amplitude {args.amplitude:g} mA: clipped to "
            f"the inlet's [{a_to_ma(valve_range_a[0]):g}, {a_to_ma(valve_range_a[1]):g}] mA "
            "nothing of the excitation is left"
        )
    run = simulate_loop(build_excitation_loop(config, applied), config)
    summary = excitation_summary(
        designed, applied, ma_to_a(args.amplitude), offset_a, valve_range_a, run
    )
    args.out.mkdir(parents=True, exist_ok=True)
    mcap_path, png_path = args.out / "run.mcap", args.out / "run.png"
    write_recording(mcap_path, recording_channels(run))
    plot_run(run, png_path, show_tolerance=False)
    summary["files"] = {"recording": str(mcap_path), "plot": str(png_path)}
    return summary


def run_command(args: argparse.Namespace) -> int:
    """`maskless excite`: returns the process exit code."""
    summary = run_excitation(args)
    print(json.dumps(summary) if args.json else format_excitation_summary(summary))
    return 0
