"""Excite the plant open loop for identification: record it to MCAP, plot it and summarise it.

Drives the inlet valve (outlet shut) with the paper's uniform white noise (Eq. 22-23), a PRBS, a
Schroeder multisine or a multilevel PRBS (random levels over the valve's whole range held for
random times, for a Hammerstein fit) about an offset current, clipped to the valve's
[0, saturation] range as the authors clipped theirs, while the cameras, their local Kalman filters
and the fusion watch the head. --valve-drive independent gives each valve its own signal, clipped
to its own range; --valve-drive split-range splits one command between them, the inlet above the
inlet's starting current and the outlet below it, as the controller does. --signal valve-levels
drives both valves through continuous stratified levels from shut to 190 mA (one valve at a time
with split-range), the design benchmarks/hammerstein.py measures the Hammerstein fit on;
--signal designed-levels (split-range) designs a stretch of those levels as the run goes, from
what the record before it shows (the sequential design whose fit places both valves' starting
currents within 5 mA on most records; fit its first 80 %). Writes
DIR/run.mcap
with the topics `maskless simulate` writes (the command topic carries both valve currents; the
reference topic holds the resting height, as nothing is commanded), DIR/run.png, and prints the
signal's standard deviation (against A/sqrt(3) for uniform noise), its crest factor and how much
of it was clipped, and per valve its current's range, standard deviation and fraction clipped. A
DIR holding a run is refused unless --overwrite; the files are renamed into place once all are
written. `maskless identify --input DIR/run.mcap --ts PERIOD` then fits a model to the recording.
"""

import argparse
import json

from maskless.diagrams.cli import (
    add_config_argument,
    add_out_argument,
    add_overwrite_argument,
    add_sensor_arguments,
    finite_number,
    given_labels,
    positive_number,
    scenario_from_flags,
)
from maskless.diagrams.excitation_design import (
    DESIGNED_LEVELS_HOLD_S,
    MULTILEVEL_HOLD_S,
    MULTILEVEL_LEVELS,
    SIGNALS,
    VALVE_DRIVES,
    ExcitationRequest,
)
from maskless.diagrams.excitation_run import excite_to_files, format_excitation_summary
from maskless.systems.units import ma_to_a

FLAG_OF_FIELD = {
    "signal": "--signal",
    "amplitude_a": "--amplitude",
    "offset_a": "--offset",
    "duration_s": "--duration",
    "sample_period_s": "--period",
    "clock_periods": "--clock-periods",
    "band_hz": "--band",
    "valve_drive": "--valve-drive",
    "levels": "--levels",
    "hold_s": "--hold",
}


def _colon_pair(text: str, expected: str) -> tuple[float, float]:
    try:
        low, high = (float(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected {expected}") from None
    return low, high


def _band(text: str) -> tuple[float, float]:
    return _colon_pair(text, "LOW:HIGH in Hz, e.g. 0.01:1")


def _hold(text: str) -> tuple[float, float]:
    return _colon_pair(text, "SHORTEST:LONGEST in s, e.g. 1:40")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless excite`."""
    parser.add_argument("--signal", choices=SIGNALS, default="uniform", help="default uniform")
    parser.add_argument(
        "--valve-drive",
        choices=VALVE_DRIVES,
        default="inlet",
        help="inlet (outlet shut; the default), independent (a signal per valve) or split-range "
        "(one command: inlet above the inlet's starting current, outlet below it)",
    )
    parser.add_argument(
        "--amplitude",
        type=positive_number,
        default=None,
        metavar="MA",
        help="half-width of the current excursion, mA (default 50; multilevel: half the valve's "
        "whole 0-saturation range)",
    )
    parser.add_argument(
        "--offset",
        type=finite_number,
        default=None,
        metavar="MA",
        help="centre current, mA (default: mid-way between the valve's starting and saturation "
        "currents, each valve's own when independent; multilevel: mid-way in 0-saturation; "
        "split-range: the inlet's starting current, where the valves split)",
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
    parser.add_argument(
        "--levels",
        type=int,
        default=MULTILEVEL_LEVELS,
        metavar="N",
        help=f"multilevel: number of evenly spaced levels (default {MULTILEVEL_LEVELS})",
    )
    parser.add_argument(
        "--hold",
        type=_hold,
        default=None,
        metavar="SHORTEST:LONGEST",
        help="multilevel, valve-levels and designed-levels: range of the random hold times, s "
        f"(default {MULTILEVEL_HOLD_S[0]:g}:{MULTILEVEL_HOLD_S[1]:g}, chosen for the pneumatic "
        f"plant's time constants; designed-levels {DESIGNED_LEVELS_HOLD_S[0]:g}:"
        f"{DESIGNED_LEVELS_HOLD_S[1]:g}, as its design was measured, and its targeted holds "
        "last the shortest, or the design's own hold if longer)",
    )
    parser.add_argument("--seed", type=int, default=None, metavar="N", help="default: the config's")
    parser.add_argument(
        "--plant",
        default=None,
        metavar="PLANT",
        help="pneumatic, paper or identified:MODEL.yaml (default: the config's, pneumatic)",
    )
    add_config_argument(parser)
    add_sensor_arguments(parser)
    add_out_argument(parser, "excitation", "run.mcap and run.png")
    add_overwrite_argument(parser)
    parser.add_argument("--json", action="store_true", help="print the summary as one JSON object")


def excitation_request(args: argparse.Namespace) -> ExcitationRequest:
    """The experiment the flags describe (currents from mA to A)."""
    return ExcitationRequest(
        signal=args.signal,
        amplitude_a=None if args.amplitude is None else ma_to_a(args.amplitude),
        offset_a=None if args.offset is None else ma_to_a(args.offset),
        duration_s=args.duration,
        sample_period_s=args.period,
        clock_periods=args.clock_periods,
        band_hz=args.band,
        valve_drive=args.valve_drive,
        levels=args.levels,
        hold_s=args.hold,
        labels=given_labels(args, FLAG_OF_FIELD),
    )


def run_command(args: argparse.Namespace) -> int:
    """`maskless excite`: returns the process exit code."""
    request = excitation_request(args)
    scenario = scenario_from_flags(
        args,
        {"--seed": "random_seed", "--plant": "plant", "--image-rate": "camera_image_rate_hz"},
    )
    summary = excite_to_files(scenario, request, args.out, overwrite=args.overwrite)
    print(json.dumps(summary) if args.json else format_excitation_summary(summary))
    return 0
