"""The paper's workflow, closed inside the product: excite -> identify -> design -> simulate.

1. excite the scenario's plant (the pneumatic one by default) open loop, and record it to
   DIR/excitation/run.mcap;
2. identify a model (--order) from the recorded command to the fused height, into
   DIR/identification/;
3. design the offset-free LQG on that model and simulate it on that plant, into
   DIR/closed_loop/.

--method pem (the paper's): the inlet alone is excited, by default with a PRBS whose bits last
2 s, because the bladder's time constants are seconds long (the paper's uniform white noise at
the frame rate, --signal uniform --clock-periods 1, leaves the input's effect below the noise),
and a linear model is fitted by prediction error. --method hammerstein: both valves are driven
through levels from shut to their top (by default designed-levels, an hour long) and each
valve's static map is fitted with the dynamics; the controller opens the valves through the
inverse of the maps it identified. Each stage prints the `maskless` command that redoes it alone.
"""

import argparse
import dataclasses
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
from maskless.diagrams.workflow import (
    METHOD_EXCITATIONS,
    WORKFLOW_METHODS,
    format_workflow,
    run_workflow,
)
from maskless.errors import ConfigError
from maskless.systems.units import ma_to_a

_EXCITATION_FLAGS = {
    "signal": "--signal",
    "amplitude_a": "--amplitude",
    "offset_a": "--offset",
    "duration_s": "--excitation-duration",
    "clock_periods": "--clock-periods",
}
_WORKFLOW_FLAGS = {
    "closed_loop_s": "--duration",
    "order": "--order",
    "random_seed": "--seed",
    "method": "--method",
}
# The PRBS's shape: the Hammerstein method's levels span each valve from shut to its top instead.
_PRBS_ONLY_FLAGS = ("--amplitude", "--offset", "--clock-periods")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless workflow`."""
    add_out_argument(parser, "workflow", "excitation/, identification/ and closed_loop/")
    add_overwrite_argument(parser)
    parser.add_argument(
        "--method",
        choices=WORKFLOW_METHODS,
        default="pem",
        help="pem: the inlet, a linear model (default); hammerstein: both valves and their maps",
    )
    parser.add_argument(
        "--signal",
        choices=SIGNALS,
        default=None,
        help="default prbs with pem, designed-levels with hammerstein",
    )
    parser.add_argument(
        "--amplitude", type=positive_number, default=None, metavar="MA", help="pem: mA (25)"
    )
    parser.add_argument(
        "--offset",
        type=finite_number,
        default=None,
        metavar="MA",
        help="pem: mA (default 130: mid-way up the lift range)",
    )
    parser.add_argument(
        "--clock-periods",
        type=int,
        default=None,
        metavar="N",
        help="pem: samples per bit (default 30, 2 s at 15 Hz)",
    )
    parser.add_argument(
        "--excitation-duration",
        type=float,
        default=None,
        metavar="S",
        help="default 600 with pem, 3600 with hammerstein",
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
    result = run_workflow(
        args.out,
        method=args.method,
        excitation=excitation_request(args),
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


def excitation_request(args: argparse.Namespace) -> ExcitationRequest:
    """The experiment the flags describe: the method's own, with the flags given over it.

    Raises:
        ConfigError: a PRBS-shape flag (``_PRBS_ONLY_FLAGS``) with --method hammerstein.
    """
    if args.method == "hammerstein":
        for flag in _PRBS_ONLY_FLAGS:
            if getattr(args, flag.removeprefix("--").replace("-", "_")) is not None:
                raise ConfigError(
                    f"{flag}: not used by --method hammerstein (its levels span each valve "
                    "from shut to its top current)"
                )
    flags = {
        "signal": args.signal,
        "amplitude_a": None if args.amplitude is None else ma_to_a(args.amplitude),
        "offset_a": None if args.offset is None else ma_to_a(args.offset),
        "duration_s": args.excitation_duration,
        "clock_periods": args.clock_periods,
    }
    given = {field: value for field, value in flags.items() if value is not None}
    return dataclasses.replace(
        METHOD_EXCITATIONS[args.method], **given, labels=given_labels(args, _EXCITATION_FLAGS)
    )
