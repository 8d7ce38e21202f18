"""Run a population of patients through the closed loop, on every core or on a Dask cluster.

Each trial draws a patient (head mass, bladder stiffness and leak, valve conductances, supply
pressure, and a reference step of 2-10 mm up or down for the standard population) and runs it
once per controller of the population file. Writes DIR/trials.csv (one row per trial and
controller: the draws, the seed and the tracking figures, judged over the same fixed window as
`maskless simulate`), DIR/summary.json and DIR/population.png (CDFs across patients and the worst
trials' traces), and prints the summary. Run again with the same DIR, it runs only the trials not
yet in its table: an interrupted sweep resumes, and a larger --trials extends one.
"""

import argparse
import json
import sys
from pathlib import Path

from maskless.diagrams.cli import add_out_argument
from maskless.diagrams.montecarlo import SweepRequest, run_sweep
from maskless.diagrams.population import load_population, population_preset_path, preset_names


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless montecarlo`."""
    source = parser.add_mutually_exclusive_group()
    source.add_argument(
        "--preset",
        default=None,
        metavar="NAME",
        help=f"a shipped population: {', '.join(preset_names())} (default: standard)",
    )
    source.add_argument(
        "--population",
        type=Path,
        default=None,
        metavar="FILE.yaml",
        help="a population file of your own (the presets in assets/presets/population_*.yaml "
        "show its fields)",
    )
    parser.add_argument(
        "--trials",
        type=_count,
        default=None,
        metavar="N",
        help="patients to draw, each run with every controller (default: the population's)",
    )
    parser.add_argument(
        "--seeds-per-patient",
        type=_count,
        default=None,
        metavar="N",
        help="runs of each patient with different noise (default: the population's, 1)",
    )
    add_out_argument(parser, "mc", "trials.csv, summary.json and population.png")
    parser.add_argument(
        "--workers",
        type=_count,
        default=None,
        metavar="N",
        help="local processes (default: one per core; 1 runs in this process)",
    )
    parser.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="run on a Dask cluster instead: its scheduler's address (tcp://HOST:8786); start "
        "one with `dask scheduler` and `dask worker ADDRESS` where maskless is installed",
    )
    parser.add_argument(
        "--restart",
        action="store_true",
        help="discard the rows already in DIR instead of resuming them",
    )
    parser.add_argument("--no-progress", action="store_true", help="no progress bar on stderr")
    parser.add_argument(
        "--json", action="store_true", help="print the summary as one JSON object instead of text"
    )


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: expected at least 1")
    return value


def _count_of(count: int, noun: str) -> str:
    return f"{count} {noun}" + ("" if count == 1 else "s")


def run_command(args: argparse.Namespace) -> int:
    """`maskless montecarlo`: returns the process exit code (1 when a trial failed)."""
    from maskless.analysis.population_summary import summary_table

    path = args.population or population_preset_path(args.preset or "standard")
    config = load_population(path)
    if args.trials is not None:
        config.trials = args.trials
    if args.seeds_per_patient is not None:
        config.seeds_per_patient = args.seeds_per_patient
    request = SweepRequest(
        config=config,
        out=args.out,
        workers=args.workers,
        scheduler=args.scheduler,
        restart=args.restart,
        progress=not args.no_progress,
    )
    try:
        summary = run_sweep(request)
    except KeyboardInterrupt:
        print(
            f"maskless montecarlo: interrupted; the finished trials are in {args.out}: run the "
            "same command again to resume",
            file=sys.stderr,
        )
        return 130
    failed = sum(f["failed"] for f in summary["per_controller"].values())
    if args.json:
        print(json.dumps(summary))
    else:
        sweep = summary["sweep"]
        print(
            f"{config.trials} trials x {_count_of(config.seeds_per_patient, 'seed')} x "
            f"{_count_of(len(config.controllers), 'controller')} from {path} "
            f"({sweep['run_now']} run now, {sweep['resumed']} already done) in "
            f"{sweep['wall_time_s']:.1f} s on {sweep['engine']}"
        )
        print(summary_table(summary))
        for name, file in summary["files"].items():
            print(f"{name}: {file}")
    if failed:
        print(
            f"maskless montecarlo: {failed} runs failed; their rows name why "
            f"({summary['files']['trials.csv']}, column 'error')",
            file=sys.stderr,
        )
        return 1
    return 0
