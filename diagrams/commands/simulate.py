"""Simulate the closed loop: record it to MCAP, plot it and summarise it.

Runs the whole sensing and control chain (the depth cameras, their local Kalman filters,
track-to-track fusion, a controller, two valves, bladder and head) as one Drake Diagram for
--duration simulated seconds, then writes DIR/run.mcap and DIR/run.png and prints a summary (a DIR
holding a run is refused unless --overwrite; a stopped run leaves DIR/run.partial.mcap). By
default the plant is the first-principles pneumatic robot and the controller the offset-free LQG;
`--plant paper --controller paper-lqg` reproduces the seed paper's loop.

The safety supervisor (the scenario's `safety` section) sits between the controller and the
valves; a run that ends with one of its faults latched exits 3 unless --allow-fault.
"""

import argparse
import json
import sys

from maskless.diagrams.cli import (
    add_config_argument,
    add_out_argument,
    add_overwrite_argument,
    add_preset_argument,
    add_sensor_arguments,
    scenario_from_flags,
)
from maskless.diagrams.run_summary import format_summary
from maskless.diagrams.simulation import simulate_to_files

# The exit status of a run that ends with a safety fault latched (2 is a refused input; 1 a failed
# trial of a sweep).
LATCHED_FAULT_EXIT = 3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless simulate`."""
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds (default: the config's duration_s, 120)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="N",
        help="random seed (default: the config's random_seed, 0)",
    )
    add_out_argument(parser, "out", "run.mcap and run.png")
    add_overwrite_argument(parser)
    add_config_argument(parser)
    add_preset_argument(parser)
    add_sensor_arguments(parser)
    parser.add_argument(
        "--plant",
        default=None,
        metavar="PLANT",
        help="pneumatic (the first-principles robot), paper (Eq. 25-26) or identified:MODEL.yaml "
        "(a model `maskless identify` wrote, output the head height); default: the config's, "
        "pneumatic",
    )
    parser.add_argument(
        "--controller",
        default=None,
        metavar="CONTROLLER",
        help="offset-free-lqg (designed on the plant), offset-free-lqg:MODEL.yaml (designed on an "
        "identified model) or paper-lqg (the paper's gains); default: the config's, "
        "offset-free-lqg",
    )
    parser.add_argument(
        "--json", action="store_true", help="print the summary as one JSON object instead of text"
    )
    parser.add_argument(
        "--allow-fault",
        action="store_true",
        help="exit 0 even when the run ends with a safety fault latched (by default such a run "
        f"exits {LATCHED_FAULT_EXIT}, so a script notices it)",
    )


def run_command(args: argparse.Namespace) -> int:
    """`maskless simulate`: returns the process exit code."""
    scenario = scenario_from_flags(
        args,
        {
            "--duration": "duration_s",
            "--seed": "random_seed",
            "--plant": "plant",
            "--controller": "controller",
            "--image-rate": "camera_image_rate_hz",
        },
    )
    summary = simulate_to_files(scenario, args.out, overwrite=args.overwrite)
    print(json.dumps(summary) if args.json else format_summary(summary))
    latched = summary.get("safety", {}).get("latched_at_end")
    if latched and not args.allow_fault:
        print(
            f"maskless simulate: the run ended with a safety fault latched ({', '.join(latched)}); "
            f"exit {LATCHED_FAULT_EXIT} (--allow-fault to exit 0)",
            file=sys.stderr,
        )
        return LATCHED_FAULT_EXIT
    return 0
