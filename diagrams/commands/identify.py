"""Identify models from a recorded experiment: MATLAB's figures, the baselines a model must beat,
and a verdict on whether the input explains the output.

Reads the input (valve current) and output (head distance or height) from CSV files (one value per
line, or a column) or from a maskless MCAP recording (TOPIC:FIELD), detrends them, fits each order
on the estimation part and judges it on both parts. Writes DIR/report.json, one model file per order
(discrete A, B, C, D, K, Ts, offsets and units, as YAML), compare plots and residual plots.
"""

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np
import yaml

from maskless.analysis.identification.model_file import model_file_contents
from maskless.analysis.identification.plots import plot_compare, plot_residuals
from maskless.analysis.identification.records import (
    detrend,
    parse_range,
    read_csv_signal,
    read_mcap_signals,
)
from maskless.analysis.identification.report import METHODS, Part, identify
from maskless.analysis.identification.subspace import default_horizon
from maskless.diagrams.background import BackgroundTask
from maskless.errors import RecordError
from maskless.recording import COMMAND_TOPIC, FUSION_TOPIC

# What `maskless identify` reports as a message rather than a traceback.
USER_ERRORS = (RecordError, FileNotFoundError)

# Records at least this long report the optimiser's progress on stderr.
_PROGRESS_MIN_SAMPLES = 50_000
# A maskless recording's field names end in their SI unit.
_FIELD_UNITS = {"_a": "A", "_m": "m"}
# How far --ts may be from a recording's own sample period before it is refused.
_TS_TOLERANCE = 0.01


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
        help="CSV column, or MCAP TOPIC:FIELD (default for MCAP: /controller/command:current_a)",
    )
    parser.add_argument(
        "--output-column",
        default=None,
        metavar="NAME|INDEX|TOPIC:FIELD",
        help="CSV column, or MCAP TOPIC:FIELD (default for MCAP: /fusion/estimate:position_m)",
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
        choices=METHODS,
        default="pem",
        help="pem: innovations-form state space; armax: the same by polynomials; "
        "arx: least squares (default pem)",
    )
    parser.add_argument(
        "--estimation",
        default="0:0.6",
        metavar="START:STOP",
        help="fractions (0:0.6) or sample indices (0:11782); default 0:0.6",
    )
    parser.add_argument(
        "--validation",
        default="0.6:1",
        metavar="START:STOP",
        help="the part the models are judged on; default 0.6:1",
    )
    parser.add_argument(
        "--detrend",
        choices=("mean", "linear", "none"),
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
        help="unit of the input: m, mm, A or mA (default mA for CSV, the field's unit for MCAP)",
    )
    parser.add_argument(
        "--output-unit",
        default=None,
        help="unit of the output (default mm for CSV, the field's unit for MCAP)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("identification"),
        metavar="DIR",
        help="where the report, models and plots go (default ./identification)",
    )
    parser.add_argument("--json", action="store_true", help="print report.json to stdout")


def _field_unit(topic_and_field: str) -> str:
    for suffix, unit in _FIELD_UNITS.items():
        if topic_and_field.endswith(suffix):
            return unit
    return "unknown"


def read_signals(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray, tuple[str, str]]:
    """The input and output records and their units, refused with the file named when they
    cannot be used."""
    output_path = args.output or args.input
    if args.input.suffix == ".mcap" or output_path.suffix == ".mcap":
        input_field = args.input_column or f"{COMMAND_TOPIC}:current_a"
        output_field = args.output_column or f"{FUSION_TOPIC}:position_m"
        if output_path == args.input:  # one recording holds both: read it once
            (input_times, u), (output_times, y) = read_mcap_signals(
                args.input, input_field, output_field
            )
        else:
            ((input_times, u),) = read_mcap_signals(args.input, input_field)
            ((output_times, y),) = read_mcap_signals(output_path, output_field)
        common, input_index, output_index = np.intersect1d(
            input_times, output_times, return_indices=True
        )
        if common.size < 2:
            raise RecordError(f"{args.input} and {output_path}: fewer than 2 common timestamps")
        steps_s = np.diff(common) * 1e-9
        period_s = float(np.median(steps_s))
        if abs(period_s - args.ts) > _TS_TOLERANCE * period_s:
            raise RecordError(f"--ts {args.ts}: the recording's samples are {period_s:.6g} s apart")
        if np.any(np.abs(steps_s - period_s) > 0.5 * period_s):
            gap = int(np.argmax(np.abs(steps_s - period_s) > 0.5 * period_s))
            raise RecordError(
                f"{args.input}: {input_field} and {output_field} share no samples between "
                f"{common[gap] * 1e-9:.3f} s and {common[gap + 1] * 1e-9:.3f} s; a record with "
                "gaps cannot be identified as one sequence"
            )
        units = (_field_unit(input_field), _field_unit(output_field))
        return u[input_index], y[output_index], units
    if args.output is None:
        raise RecordError("--output is required when --input is a CSV file")
    u = read_csv_signal(args.input, args.input_column)
    y = read_csv_signal(args.output, args.output_column)
    if u.size != y.size:
        raise RecordError(
            f"{args.input} has {u.size} values but {args.output} has {y.size}; expected one "
            "output per input"
        )
    return u, y, ("mA", "mm")


def parse_orders(text: str) -> list[int]:
    try:
        orders = [int(part) for part in text.split(",")]
    except ValueError:
        raise RecordError(f"--orders {text!r}: expected positive integers, e.g. 2,4") from None
    if not orders or min(orders) < 1:
        raise RecordError(f"--orders {text!r}: expected positive integers, e.g. 2,4")
    return orders


def minimum_samples(orders: list[int], method: str) -> int:
    """The fewest samples a part needs for the largest order (N4SID's Hankel matrices need more)."""
    largest = max(orders)
    return 12 * default_horizon(largest) if method == "n4sid" else 10 * largest


def write_outputs(fitted_models, parts, report, offsets, units, args) -> None:
    """Model files and report.json here; the plots on the second core meanwhile."""
    args.out.mkdir(parents=True, exist_ok=True)

    def plots():
        for fitted in fitted_models:
            stem = f"{fitted.method}_order{fitted.model.order}"
            plot_compare(args.out / f"compare_{stem}.png", fitted, parts, args.ts, units[1])
            plot_residuals(args.out / f"residuals_{stem}.png", fitted, parts)

    plotting = BackgroundTask(f"plotting into {args.out}", plots)
    linear = args.detrend == "linear"
    for fitted, entry in zip(fitted_models, report["models"], strict=True):
        contents = model_file_contents(
            fitted,
            input_unit=units[0],
            output_unit=units[1],
            input_offset=offsets.input_offset,
            output_offset=offsets.output_offset,
            detrend=args.detrend,
            trend_slopes_per_sample=(offsets.input_slope, offsets.output_slope) if linear else None,
            verdict=entry["verdict"],
        )
        path = args.out / f"model_{fitted.method}_order{fitted.model.order}.yaml"
        path.write_text(yaml.safe_dump(contents, sort_keys=False))
        entry["model_file"] = str(path)
    (args.out / "report.json").write_text(json.dumps(report, indent=1))
    plotting.wait()


def run_command(args: argparse.Namespace) -> int:
    """`maskless identify`: returns the process exit code."""
    report = run_identification(args)
    print(json.dumps(report) if args.json else format_report(report, args.out))
    return 0


def run_identification(args: argparse.Namespace) -> dict:
    """Fits, judges and writes the models ``args`` ask for; returns the report."""
    if not (math.isfinite(args.ts) and args.ts > 0):
        raise RecordError(f"--ts {args.ts}: expected a positive, finite sample period in s")
    orders = parse_orders(args.orders)
    u, y, units = read_signals(args)
    units = (args.input_unit or units[0], args.output_unit or units[1])
    if np.ptp(u) == 0:
        raise RecordError(f"{args.input}: the input is constant, so it explains nothing to fit")
    estimation_slice = parse_range(args.estimation, y.size, "--estimation")
    validation_slice = parse_range(args.validation, y.size, "--validation")
    needed = minimum_samples(orders, args.method)
    for flag, part in (("--estimation", estimation_slice), ("--validation", validation_slice)):
        if part.stop - part.start < needed:
            raise RecordError(
                f"{flag} selects {part.stop - part.start} samples; order {max(orders)} with "
                f"{args.method} needs at least {needed}"
            )
        if args.k_step is not None and args.k_step >= part.stop - part.start:
            raise RecordError(f"--k-step {args.k_step}: longer than the {flag} part")
    offsets = detrend(u, y, args.detrend)
    parts = [
        Part("estimation", offsets.u[estimation_slice], offsets.y[estimation_slice]),
        Part("validation", offsets.u[validation_slice], offsets.y[validation_slice]),
    ]
    overlap = max(estimation_slice.start, validation_slice.start) < min(
        estimation_slice.stop, validation_slice.stop
    )

    def report_progress(evaluations, cost):
        print(f"fitting: {evaluations} evaluations, cost {cost:.6g}", file=sys.stderr, flush=True)

    long_record = parts[0].y.size >= _PROGRESS_MIN_SAMPLES
    report, fitted_models = identify(
        args.method,
        parts[0],
        parts[1],
        orders,
        args.ts,
        estimate_initial_state=args.initial_state == "estimate",
        progress=report_progress if long_record else None,
        k_step=args.k_step,
        overlap=overlap,
    )
    report["record"] = {
        "samples": int(y.size),
        "estimation": [estimation_slice.start, estimation_slice.stop],
        "validation": [validation_slice.start, validation_slice.stop],
        "detrend": args.detrend,
        "input_offset": offsets.input_offset,
        "output_offset": offsets.output_offset,
        "units": {"input": units[0], "output": units[1]},
    }
    write_outputs(fitted_models, parts, report, offsets, units, args)
    return report


def format_report(report: dict, out: Path) -> str:
    """The report as lines a person reads."""
    lines = []
    for model in report["models"]:
        stability = "stable" if model["stable"] else "UNSTABLE"
        lines.append(
            f"{model['method']} order {model['order']} ({model['parameters']} parameters, "
            f"initial state {model['initial_state']}, {stability})"
        )
        for name in ("estimation", "validation"):
            part = model[name]
            k_steps = [key for key in part if key.endswith("step") and key != "fit_percent_1step"]
            extra = "".join(
                f", {key.removeprefix('fit_percent_')} {part[key]:.3f} %" for key in k_steps
            )
            lines.append(
                f"  {name:<10} fit 1-step {part['fit_percent_1step']:.6f} %{extra}, "
                f"sim {part['fit_percent_sim']:.2f} %, MSE {part['mse']:.6g}, "
                f"FPE {part['fpe']:.6g}, n {part['n']}"
            )
        margins = model["margins_on_validation"]
        lines.append(
            "  margins on validation (fit points): "
            + ", ".join(f"{name} {value:+.3f}" for name, value in margins.items())
        )
        if "warning" in model:
            lines.append(f"  WARNING: {model['warning']}")
    naive = report["baselines"]["naive_last_value"]
    lines.append(
        "baseline 'next value = last value': fit 1-step "
        + ", ".join(f"{name} {part['fit_percent_1step']:.3f} %" for name, part in naive.items())
    )
    lines += [f"WARNING: {warning}" for warning in report["warnings"]]
    lines += ["", report["verdict"], "", f"report, models and plots in {out}"]
    return "\n".join(lines)
