"""Identify models from a recorded experiment, with MATLAB's figures, baselines and a verdict.

The baselines are those a model must beat; the verdict says whether the input explains the output.

Reads the input (valve current) and output (head distance or height) from CSV files (one value per
line, or a column) or from a maskless MCAP recording (TOPIC:FIELD), detrends them, fits each order
on the estimation part and judges it on both parts. Writes DIR/report.json, one model file per order
(discrete A, B, C, D, K, Ts, offsets and units, as YAML), compare plots and residual plots.

Several inputs (the inlet and the outlet valve, --input-column TOPIC:FIELD,FIELD or NAME,NAME) give
one model of several inputs (B with a column each), reported per input; the designs and plants
drive one input and refuse its model file in one line.
"""

import argparse
import json
from pathlib import Path

from maskless.analysis.identification import METHODS
from maskless.analysis.identification.model_file import MODEL_FILE_UNITS
from maskless.analysis.identification.records import VALVE_CURRENTS_FIELDS
from maskless.diagrams.cli import add_out_argument, given_labels
from maskless.diagrams.fit_split import DEFAULT_ESTIMATION, DEFAULT_VALIDATION
from maskless.diagrams.identification_request import (
    DEFAULT_MCAP_INPUT,
    DEFAULT_MCAP_OUTPUT,
    DETREND_MODES,
    IdentificationRequest,
)
from maskless.diagrams.plot_worker import start_plot_worker
from maskless.errors import ConfigError

# The request's fields as the flags name them, so an error names the flag that was given.
FLAG_OF_FIELD = {
    "input": "--input",
    "output": "--output",
    "ts": "--ts",
    "orders": "--orders",
    "estimation": "--estimation",
    "validation": "--validation",
    "detrend": "--detrend",
    "k_step": "--k-step",
    "input_unit": "--input-unit",
    "output_unit": "--output-unit",
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless identify`."""
    parser.add_argument(
        "--input", required=True, type=Path, metavar="U.csv|RUN.mcap", help="the input record"
    )
    parser.add_argument(
        "--output",
        type=Path,
        metavar="Y.csv|RUN.mcap",
        help="the output record (default: the --input MCAP)",
    )
    parser.add_argument(
        "--input-column",
        default=None,
        metavar="NAME|INDEX|TOPIC:FIELD",
        help=f"CSV column, or MCAP TOPIC:FIELD (default for MCAP: {DEFAULT_MCAP_INPUT}); "
        "several inputs as NAME,NAME or TOPIC:FIELD,FIELD (both valves: "
        f"{VALVE_CURRENTS_FIELDS}, the default of --method hammerstein) for one model of "
        "several inputs",
    )
    parser.add_argument(
        "--output-column",
        default=None,
        metavar="NAME|INDEX|TOPIC:FIELD",
        help=f"CSV column, or MCAP TOPIC:FIELD (default for MCAP: {DEFAULT_MCAP_OUTPUT})",
    )
    parser.add_argument(
        "--ts",
        type=float,
        required=True,
        metavar="S",
        help="sample period in s (the paper's record: 0.048)",
    )
    parser.add_argument(
        "--orders",
        default="2",
        metavar="N[,N...]",
        help="model orders, comma-separated (default 2)",
    )
    parser.add_argument(
        "--method",
        choices=(*METHODS, "hammerstein"),
        default="pem",
        help="pem: innovations-form state space; armax: the same by polynomials; "
        "arx: least squares; n4sid: subspace (PO-MOESP); hammerstein: each valve's static map "
        "and the dynamics, from a recording of both valves (default pem)",
    )
    parser.add_argument(
        "--estimation",
        default=None,
        metavar="START:STOP",
        help=f"fractions (0:0.6) or sample indices (0:11782); default {DEFAULT_ESTIMATION}, or "
        "for --method hammerstein the part a designed recording was designed to be fitted on",
    )
    parser.add_argument(
        "--validation",
        default=None,
        metavar="START:STOP",
        help=f"the part the models are judged on; default {DEFAULT_VALIDATION}, or for --method "
        "hammerstein a designed recording's own",
    )
    parser.add_argument(
        "--detrend",
        choices=DETREND_MODES,
        default="mean",
        help="remove the whole record's mean (the authors' preprocessing, "
        "default), its trend line, or nothing",
    )
    parser.add_argument(
        "--k-step",
        type=int,
        default=None,
        metavar="K",
        help="also report the K-step-ahead prediction fit",
    )
    parser.add_argument(
        "--initial-state",
        choices=("estimate", "zero"),
        default="estimate",
        help="estimate x(0) with the model (default) or fix it at zero",
    )
    parser.add_argument(
        "--input-unit",
        default=None,
        metavar="UNIT",
        help="unit of the input, any text, shown as given (default mA for CSV, the field's unit "
        f"for MCAP; several inputs: one for all or UNIT,UNIT); only "
        f"{', '.join(MODEL_FILE_UNITS)} convert to the SI a design loads",
    )
    parser.add_argument(
        "--output-unit",
        default=None,
        metavar="UNIT",
        help="unit of the output, e.g. mm or degC (default mm for CSV, the field's unit for MCAP)",
    )
    add_out_argument(parser, "identification", "the report, models and plots")
    parser.add_argument("--json", action="store_true", help="print report.json to stdout")
    parser.add_argument(
        "--no-plots",
        action="store_true",
        help="write the report and model files only, no PNGs (for scripted runs: no plotting "
        "process and no matplotlib import; an order-2 PEM fit of 20,000 samples then takes "
        "about half the time)",
    )


def parse_orders(text: str) -> list[int]:
    """``--orders 2,4`` as a list of positive integers."""
    try:
        orders = [int(part) for part in text.split(",")]
    except ValueError:
        orders = []
    if not orders or min(orders) < 1:
        raise ConfigError(f"--orders {text!r}: expected positive integers, e.g. 2,4")
    return orders


def identification_request(args: argparse.Namespace) -> IdentificationRequest:
    """The request the flags describe."""
    return IdentificationRequest(
        input=args.input,
        output=args.output,
        ts=args.ts,
        orders=parse_orders(args.orders),
        method=args.method,
        input_column=args.input_column,
        output_column=args.output_column,
        estimation=DEFAULT_ESTIMATION if args.estimation is None else args.estimation,
        validation=DEFAULT_VALIDATION if args.validation is None else args.validation,
        detrend=args.detrend,
        k_step=args.k_step,
        estimate_initial_state=args.initial_state == "estimate",
        input_unit=args.input_unit,
        output_unit=args.output_unit,
        labels=given_labels(args, FLAG_OF_FIELD),
    )


# Flags the Hammerstein fit has no use for (it judges simulation from rest on the record as
# recorded, in the recording's own units, A and m), with the value each has when not given.
_NOT_FOR_HAMMERSTEIN = {
    "--detrend": "mean",
    "--k-step": None,
    "--initial-state": "estimate",
    "--input-unit": None,
    "--output-unit": None,
}


def _run_hammerstein(args: argparse.Namespace) -> int:
    """`maskless identify --method hammerstein`; a flag it would ignore is refused by name.

    Judged by the parsed values, so an abbreviated flag (``--k-st``) is refused too.
    """
    for flag, unset in _NOT_FOR_HAMMERSTEIN.items():
        if getattr(args, flag.removeprefix("--").replace("-", "_")) != unset:
            raise ConfigError(
                f"{flag}: not used by --method hammerstein (it fits and judges the record as "
                "recorded, by simulation from rest, in the recording's units)"
            )
    from maskless.diagrams.hammerstein_run import (
        format_hammerstein_report,
        identify_hammerstein_to_files,
    )

    report = identify_hammerstein_to_files(
        args.input,
        args.ts,
        parse_orders(args.orders),
        args.out,
        estimation=args.estimation,
        validation=args.validation,
        input_field=args.input_column or VALVE_CURRENTS_FIELDS,
        output_recording=args.output,
        output_field=args.output_column or DEFAULT_MCAP_OUTPUT,
        plots=not args.no_plots,
    )
    print(json.dumps(report) if args.json else format_hammerstein_report(report))
    return 0


def run_command(args: argparse.Namespace) -> int:
    """`maskless identify`: returns the process exit code."""
    if args.method == "hammerstein":
        return _run_hammerstein(args)
    request = identification_request(args)
    # Forked before the estimators are imported: matplotlib's import overlaps scipy's.
    plotter = None if args.no_plots else start_plot_worker(args.out)
    try:
        from maskless.diagrams.identification_run import (
            format_identification_report,
            identify_to_files,
        )

        report = identify_to_files(request, args.out, plotter, plots=not args.no_plots)
    except BaseException:
        if plotter is not None:
            plotter.stop()
        raise
    print(json.dumps(report) if args.json else format_identification_report(report, args.out))
    return 0
