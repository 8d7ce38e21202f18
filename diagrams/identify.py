"""Identify models from a recorded experiment: MATLAB's figures, the baselines a model must beat,
and a verdict on whether the input explains the output.

Reads the input (valve current) and output (head distance or height) from CSV files (one value per
line, or a column) or from a maskless MCAP recording (TOPIC:FIELD), detrends them, fits each order
on the estimation part and judges it on both parts. Writes DIR/report.json, one model file per order
(discrete A, B, C, D, K, Ts, offsets and units, as YAML), compare plots and residual plots.
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import yaml

from maskless.analysis.identification_data import (
    RecordError,
    detrend,
    parse_range,
    read_csv_signal,
    read_mcap_signal,
)
from maskless.analysis.identification_report import METHODS, FittedModel, Part, identify
from maskless.analysis.residual_analysis import plot_residual_correlations, residual_correlations
from maskless.diagrams.background import BackgroundTask

# Records at least this long report the optimiser's progress on stderr.
_PROGRESS_MIN_SAMPLES = 50_000


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
    parser.add_argument("--input-unit", default="mA", help="unit of the input (default mA)")
    parser.add_argument("--output-unit", default="mm", help="unit of the output (default mm)")
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("identification"),
        metavar="DIR",
        help="where the report, models and plots go (default ./identification)",
    )
    parser.add_argument("--json", action="store_true", help="print report.json to stdout")


def read_signals(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray]:
    """The input and output records, refused with the file named when they cannot be used."""
    output_path = args.output or args.input
    if args.input.suffix == ".mcap" or output_path.suffix == ".mcap":
        input_times, u = read_mcap_signal(
            args.input, args.input_column or "/controller/command:current_a"
        )
        output_times, y = read_mcap_signal(
            output_path, args.output_column or "/fusion/estimate:position_m"
        )
        # Keep the samples both topics have (a maskless recording logs both every period).
        common, input_index, output_index = np.intersect1d(
            input_times, output_times, return_indices=True
        )
        if common.size == 0:
            raise RecordError(f"{args.input} and {output_path}: no common timestamps")
        return u[input_index], y[output_index]
    if args.output is None:
        raise RecordError("--output is required when --input is a CSV file")
    u = read_csv_signal(args.input, args.input_column)
    y = read_csv_signal(args.output, args.output_column)
    if u.size != y.size:
        raise RecordError(
            f"{args.input} has {u.size} values but {args.output} has {y.size}; expected one "
            "output per input"
        )
    return u, y


def parse_orders(text: str) -> list[int]:
    try:
        orders = [int(part) for part in text.split(",")]
    except ValueError:
        raise RecordError(f"--orders {text!r}: expected positive integers, e.g. 2,4") from None
    if not orders or min(orders) < 1:
        raise RecordError(f"--orders {text!r}: expected positive integers, e.g. 2,4")
    return orders


def model_file(fitted: FittedModel, args, offsets) -> dict:
    """A model as the YAML a later `maskless simulate --plant identified:FILE` and the LQG design
    read: discrete matrices, Ts, the offsets removed before fitting and the units."""
    matrices = fitted.model.state_space()
    return {
        "method": fitted.method,
        "order": fitted.model.order,
        "sample_period_s": args.ts,
        **{name: matrix.tolist() for name, matrix in matrices.items()},
        "input": {"unit": args.input_unit, "offset": offsets.input_offset},
        "output": {"unit": args.output_unit, "offset": offsets.output_offset},
        "detrend": args.detrend,
        "stable": fitted.model.is_stable(),
    }


def plot_compare(path: Path, fitted: FittedModel, parts: list[Part], args) -> None:
    """Measured output against the one-step prediction and the simulation, on each part."""
    from matplotlib.figure import Figure  # a bare Figure: no GUI backend, no pyplot

    model = fitted.model
    figure = Figure(figsize=(11, 3.2 * len(parts)), layout="constrained")
    axes = figure.subplots(len(parts), 1, squeeze=False)[:, 0]
    for axis, part in zip(axes, parts, strict=True):
        estimated = fitted.estimated_initial_state
        x0_step = model.initial_state_for(part.u, part.y, "one_step") if estimated else None
        x0_sim = model.initial_state_for(part.u, part.y, "simulation") if estimated else None
        time_s = np.arange(part.y.size) * args.ts
        axis.plot(time_s, part.y, color="black", lw=0.8, label="measured")
        axis.plot(time_s, model.predict(part.u, part.y, x0_step), lw=0.7, label="1-step prediction")
        axis.plot(time_s, model.simulate(part.u, x0_sim), lw=1.0, label="simulation")
        axis.set_title(f"{fitted.method} order {model.order}: {part.name} part")
        axis.set_ylabel(f"output - offset ({args.output_unit})")
        axis.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time from the part's start (s)")
    figure.savefig(path, dpi=100)


def write_plots(fitted_models, parts, args) -> None:
    for fitted in fitted_models:
        stem = f"{fitted.method}_order{fitted.model.order}"
        plot_compare(args.out / f"compare_{stem}.png", fitted, parts, args)
        estimation = parts[0]
        residuals = estimation.y - fitted.model.predict(estimation.u, estimation.y)
        plot_residual_correlations(
            args.out / f"residuals_{stem}.png",
            residual_correlations(residuals, estimation.u),
            f"{fitted.method} order {fitted.model.order}, estimation part",
        )


def run_command(args: argparse.Namespace) -> int:
    """`maskless identify`: returns the process exit code."""
    if not args.ts > 0:
        raise RecordError(f"--ts {args.ts}: expected a positive sample period in s")
    orders = parse_orders(args.orders)
    if args.k_step is not None and args.k_step < 1:
        raise RecordError(f"--k-step {args.k_step}: expected a positive number of samples")
    u, y = read_signals(args)
    estimation_slice = parse_range(args.estimation, y.size, "--estimation")
    validation_slice = parse_range(args.validation, y.size, "--validation")
    offsets = detrend(u, y, args.detrend)
    parts = [
        Part("estimation", offsets.u[estimation_slice], offsets.y[estimation_slice]),
        Part("validation", offsets.u[validation_slice], offsets.y[validation_slice]),
    ]

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
    )
    report["record"] = {
        "samples": int(y.size),
        "estimation": [estimation_slice.start, estimation_slice.stop],
        "validation": [validation_slice.start, validation_slice.stop],
        "detrend": args.detrend,
        "input_offset": offsets.input_offset,
        "output_offset": offsets.output_offset,
    }
    args.out.mkdir(parents=True, exist_ok=True)
    plotting = BackgroundTask(f"plotting into {args.out}", write_plots, fitted_models, parts, args)
    for fitted in fitted_models:
        path = args.out / f"model_{fitted.method}_order{fitted.model.order}.yaml"
        path.write_text(yaml.safe_dump(model_file(fitted, args, offsets), sort_keys=False))
    (args.out / "report.json").write_text(json.dumps(report, indent=1))
    plotting.wait()
    if args.json:
        print(json.dumps(report))
    else:
        print(format_report(report, args.out))
    return 0


def format_report(report: dict, out: Path) -> str:
    """The report as lines a person reads."""
    lines = []
    for model in report["models"]:
        e, v = model["estimation"], model["validation"]
        stability = "stable" if model["stable"] else "UNSTABLE"
        lines.append(
            f"{model['method']} order {model['order']} ({model['parameters']} parameters, "
            f"initial state {model['initial_state']}, {stability})"
        )
        for name, part in (("estimation", e), ("validation", v)):
            lines.append(
                f"  {name:<10} fit 1-step {part['fit_percent_1step']:.6f} %, "
                f"sim {part['fit_percent_sim']:.2f} %, MSE {part['mse']:.6g}, "
                f"FPE {part['fpe']:.6g}, n {part['n']}"
            )
        beaten = [name for name, beats in model["beats_on_validation"].items() if not beats]
        if beaten:
            lines.append(f"  does not beat on validation: {', '.join(beaten)}")
        if "warning" in model:
            lines.append(f"  WARNING: {model['warning']}")
    naive = report["baselines"]["naive_last_value"]
    lines.append(
        "baseline 'next value = last value': fit 1-step "
        + ", ".join(
            f"{name} {figures['fit_percent_1step']:.3f} %" for name, figures in naive.items()
        )
    )
    lines += ["", report["verdict"], "", f"report, models and plots in {out}"]
    return "\n".join(lines)
