"""Analyse the pneumatic plant and the controllers: operating range and loop stability.

operating-range: for each valve current (inlet 60-165 mA with the outlet shut; outlet over its
range with the inlet fully open) the steady lift, bladder pressure, and Drake's linearisation
there: DC gain (mm/mA) and time constants. Writes DIR/operating_range.json and
DIR/operating_range.png.

stability: closed-loop poles and discrete gain, phase and delay margins of the paper's LQG on the
paper's identified model (nearly open loop), and of the offset-free LQG on the pneumatic plant
linearised where the head rests at several lifts, with head masses around the nominal one and
extra sensor latency. Writes DIR/stability.json and DIR/stability_*.png.

faults: the fault matrix. Every shipped fault example (assets/faults/*.yaml) and the nominal case,
each run with --seeds seeds on the scenario's closed loop: when each fault was detected, how soon
the safety supervisor latched its safe state, the head's worst excursion, the tracking p95, and
how long the beam was on while the head was out of tolerance or held while it was within.
Writes DIR/faults.csv (a row per run), DIR/faults.json (per case, and the issue's targets) and
DIR/faults.png; exits 1 when a target is missed.

All read the shipped configuration, or --config FILE.yaml over it (as `maskless simulate`).
"""

import argparse
import json

from maskless.diagrams.cli import (
    add_config_argument,
    add_out_argument,
    add_overwrite_argument,
    add_preset_argument,
    given_labels,
    scenario_from_flags,
)
from maskless.diagrams.fault_matrix import (
    FaultMatrixRequest,
    format_fault_matrix,
    run_fault_matrix,
)
from maskless.diagrams.plant_analysis import (
    StabilityRequest,
    analyze_operating_range,
    analyze_stability,
    format_operating_range,
    format_stability,
)
from maskless.errors import ConfigError
from maskless.systems.units import mm_to_m

_FLAG_OF_FIELD = {
    "lifts_m": "--lifts",
    "mass_factors": "--mass-factors",
    "extra_latency_ticks": "--extra-latency-ticks",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The subcommands and flags of `maskless analyze`."""
    analyses = parser.add_subparsers(dest="analysis", required=True, metavar="ANALYSIS")
    operating = analyses.add_parser(
        "operating-range",
        help="steady lift, pressure, gain and time constants against valve current",
        description="Steady lift, bladder pressure, linearised DC gain and time constants of the "
        "pneumatic plant against each valve's current.",
    )
    operating.add_argument(
        "--points",
        type=int,
        default=22,
        metavar="N",
        help="currents per valve, evenly spaced from starting to saturation current "
        "(default 22: every 5 mA over 60-165 mA)",
    )
    stability = analyses.add_parser(
        "stability",
        help="closed-loop poles and margins of the paper's LQG and of the offset-free LQG",
        description="Closed-loop poles and gain, phase and delay margins of the paper's LQG on "
        "its identified model and of the offset-free LQG on the linearised pneumatic plant, "
        "against lift, head mass and sensor latency.",
    )
    stability.add_argument(
        "--lifts",
        default="2,5,9,13",
        metavar="MM[,MM...]",
        help="lifts the head rests at, in mm (default 2,5,9,13)",
    )
    stability.add_argument(
        "--mass-factors",
        default="0.8,1.2",
        metavar="F[,F...]",
        help="head masses as factors on the configured head's (pneumatic.head_mass_kg); 1 is "
        "always included (default 0.8,1.2)",
    )
    stability.add_argument(
        "--extra-latency-ticks",
        default="1,2",
        metavar="N[,N...]",
        help="sensor latency beyond the designed-for delay, in controller ticks (1/15 s); 0 is "
        "always included (default 1,2)",
    )
    faults = analyses.add_parser(
        "faults",
        help="the fault matrix: every fault example x seeds, detection, safe state and beam",
        description="Every shipped fault example and the nominal case x --seeds seeds: detection "
        "latency, time to the safe state, worst head excursion, and the beam's time on while the "
        "head was out of tolerance or held while it was within.",
    )
    faults.add_argument(
        "--seeds", type=int, default=20, metavar="N", help="runs per case (default 20)"
    )
    faults.add_argument(
        "--faults",
        default=None,
        metavar="NAME[,NAME...]",
        help="the cases: fault examples by name (faults/NAME.yaml or NAME) and nominal "
        "(default: every shipped example and nominal)",
    )
    faults.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds per run (default: the config's duration_s, 120)",
    )
    faults.add_argument(
        "--workers", type=int, default=None, metavar="N", help="processes (default: every core)"
    )
    add_overwrite_argument(faults)
    add_preset_argument(faults)
    for sub in (operating, stability, faults):
        add_out_argument(sub, "analysis_out", "the JSON and the plots")
        add_config_argument(sub)
        sub.add_argument(
            "--json",
            action="store_true",
            help="print the JSON report as one line instead of the text",
        )


def _parse_list(text: str, flag: str, convert, expected: str) -> list:
    try:
        return [convert(part) for part in text.split(",")]
    except ValueError:
        raise ConfigError(f"{flag} {text!r}: expected {expected}, separated by commas") from None


def stability_request(args: argparse.Namespace) -> StabilityRequest:
    """The cases the flags ask for (lifts from mm to m)."""
    lifts_mm = _parse_list(args.lifts, "--lifts", float, "lifts in mm")
    return StabilityRequest(
        lifts_m=tuple(mm_to_m(lift) for lift in lifts_mm),
        mass_factors=tuple(_parse_list(args.mass_factors, "--mass-factors", float, "factors")),
        extra_latency_ticks=tuple(
            _parse_list(args.extra_latency_ticks, "--extra-latency-ticks", int, "whole ticks")
        ),
        labels=given_labels(args, _FLAG_OF_FIELD),
    )


def run_command(args: argparse.Namespace) -> int:
    """`maskless analyze`: returns the process exit code."""
    if args.analysis == "faults":
        return _fault_matrix(args)
    if args.analysis == "operating-range":
        scenario = scenario_from_flags(args, {})
        report = analyze_operating_range(scenario, args.points, args.out, points_label="--points")
        text = format_operating_range(report, scenario.pneumatic.head_mass_kg)
    else:
        request = stability_request(args)
        scenario = scenario_from_flags(args, {})
        report = analyze_stability(scenario, request, out=args.out)
        text = format_stability(report)
    print(json.dumps(report) if args.json else text)
    return 0


def _fault_matrix(args: argparse.Namespace) -> int:
    if args.workers is not None and args.workers < 1:
        raise ConfigError(f"--workers {args.workers}: expected at least 1")
    scenario = scenario_from_flags(args, {"--duration": "duration_s"})
    cases = () if args.faults is None else tuple(_parse_list(args.faults, "--faults", str, "names"))
    summary = run_fault_matrix(
        FaultMatrixRequest(
            out=args.out,
            scenario=scenario,
            cases=cases,
            seeds=args.seeds,
            workers=args.workers,
            overwrite=args.overwrite,
        )
    )
    print(json.dumps(summary) if args.json else format_fault_matrix(summary))
    return 0 if summary["all_targets_met"] else 1
