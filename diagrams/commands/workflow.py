"""The paper's workflow, closed inside the product: excite -> identify -> design -> simulate.

1. excite the scenario's plant (the pneumatic one by default) on its inlet, open loop, and record
   it to DIR/excitation/run.mcap;
2. identify a state-space model (prediction error, --order) from the recorded command to the fused
   height, into DIR/identification/;
3. design the offset-free LQG on that model and simulate it on that plant, into
   DIR/closed_loop/.

Each stage prints the `maskless` command that redoes it alone. The default PRBS holds each bit
2 s, because the bladder's time constants are seconds long; the paper's uniform white noise at
the frame rate (--signal uniform --clock-periods 1) leaves the input's effect below the noise.
"""

import argparse
import json

from maskless.diagrams.cli import (
    add_config_argument,
    add_out_argument,
    add_overwrite_argument,
    finite_number,
    given_labels,
    positive_number,
)
from maskless.diagrams.excitation_run import SIGNALS, ExcitationRequest
from maskless.diagrams.workflow import format_workflow, run_workflow
from maskless.systems.units import ma_to_a

_EXCITATION_FLAGS = {
    "signal": "--signal",
    "amplitude_a": "--amplitude",
    "offset_a": "--offset",
    "duration_s": "--excitation-duration",
    "clock_periods": "--clock-periods",
}
_WORKFLOW_FLAGS = {"closed_loop_s": "--duration", "order": "--order", "random_seed": "--seed"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless workflow`."""
    add_out_argument(parser, "workflow", "excitation/, identification/ and closed_loop/")
    add_overwrite_argument(parser)
    parser.add_argument("--signal", choices=SIGNALS, default="prbs", help="default prbs")
    parser.add_argument(
        "--amplitude", type=positive_number, default=25.0, metavar="MA", help="mA (default 25)"
    )
    parser.add_argument(
        "--offset",
        type=finite_number,
        default=130.0,
        metavar="MA",
        help="mA (default 130: mid-way up the lift range)",
    )
    parser.add_argument(
        "--clock-periods",
        type=int,
        default=30,
        metavar="N",
        help="prbs: samples per bit (default 30, 2 s at 15 Hz)",
    )
    parser.add_argument(
        "--excitation-duration", type=float, default=600.0, metavar="S", help="default 600"
    )
    parser.add_argument("--order", type=int, default=2, metavar="N", help="model order, 2")
    parser.add_argument(
        "--duration", type=float, default=120.0, metavar="S", help="closed loop, s (default 120)"
    )
    parser.add_argument(
        "--seed", type=int, default=None, metavar="N", help="default: the config's, 0"
    )
    add_config_argument(parser)
    parser.add_argument("--json", action="store_true", help="print the summaries as one JSON")


def run_command(args: argparse.Namespace) -> int:
    """`maskless workflow`: returns the process exit code."""
    excitation = ExcitationRequest(
        signal=args.signal,
        amplitude_a=ma_to_a(args.amplitude),
        offset_a=ma_to_a(args.offset),
        duration_s=args.excitation_duration,
        clock_periods=args.clock_periods,
        labels=given_labels(args, _EXCITATION_FLAGS),
    )
    result = run_workflow(
        args.out,
        excitation=excitation,
        order=args.order,
        closed_loop_s=args.duration,
        seed=args.seed,
        config=args.config,
        echo=(lambda line: None) if args.json else print,
        labels=given_labels(args, _WORKFLOW_FLAGS),
        overwrite=args.overwrite,
    )
    print(json.dumps(result) if args.json else format_workflow(result))
    return 0
