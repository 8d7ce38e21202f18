"""The paper's workflow, closed inside the product: excite -> identify -> design -> simulate.

1. `maskless excite` drives the pneumatic plant's inlet open loop and records the cameras, filters
   and fusion to DIR/excitation/run.mcap;
2. `maskless identify` fits a state-space model (prediction error, the order given) from the
   recorded command to the fused height, into DIR/identification/;
3. `maskless simulate --controller offset-free-lqg:MODEL.yaml` designs the offset-free LQG on that
   model with Drake's Riccati solvers and closes the loop on the pneumatic plant, into
   DIR/closed_loop/.

Each stage is the command of the same name, run in process with the arguments printed, so any
stage can be re-run by hand. The default excitation is a PRBS whose bits last 2 s: the bladder's
time constants are seconds long, and the paper's uniform white noise at the frame rate
(`--signal uniform --clock-periods 1`) puts so little power below 1 Hz that the identified input
gain is noise, as it was for the authors (shared/paper-data/README.md).
"""

import argparse
import json
import math
import shlex
import sys
from pathlib import Path

from maskless.analysis.identification.report import EXPLAINS_VERDICT
from maskless.analysis.summary import tracking_lines
from maskless.diagrams.cli import add_config_argument
from maskless.diagrams.commands import excite, identify, simulate
from maskless.diagrams.commands.excite import SIGNALS
from maskless.errors import ConfigError, RecordError

USER_ERRORS = (ConfigError, FileNotFoundError, ValueError, RecordError)


def _stage_args(module, argv: list[str]) -> argparse.Namespace:
    """``argv`` parsed by the stage's own command-line parser (its defaults and checks)."""
    parser = argparse.ArgumentParser(prog=f"maskless {module.__name__.rsplit('.', 1)[-1]}")
    module.add_arguments(parser)
    return parser.parse_args(argv)


def run_workflow(
    out: Path,
    *,
    signal: str = "prbs",
    amplitude_ma: float = 25.0,
    offset_ma: float = 130.0,
    clock_periods: int = 30,
    excitation_s: float = 600.0,
    order: int = 2,
    closed_loop_s: float = 120.0,
    seed: int = 0,
    config: Path | None = None,
    echo=print,
) -> dict:
    """Runs the three stages into ``out`` and returns their summaries.

    Args:
        out: the directory for excitation/, identification/ and closed_loop/.
        signal, amplitude_ma, offset_ma, clock_periods, excitation_s: the experiment
            (`maskless excite`'s --signal, --amplitude, --offset, --clock-periods, --duration).
        order: the identified model's order (the paper's is 2).
        closed_loop_s: the closed-loop simulation's duration (s).
        seed: the seed of both simulations.
        config: a YAML overriding the shipped scenario, for both simulations.
        echo: called with each stage's command line.
    """
    for flag, value in (("--excitation-duration", excitation_s), ("--duration", closed_loop_s)):
        if not (math.isfinite(value) and value > 0):
            raise ValueError(f"{flag} {value}: expected a positive number of seconds")
    if order < 1:
        raise ValueError(f"--order {order}: expected a model order of at least 1")
    common = ["--seed", str(seed)] + ([] if config is None else ["--config", str(config)])
    excite_argv = [
        "--signal", signal,
        "--amplitude", repr(amplitude_ma),
        "--offset", repr(offset_ma),
        "--clock-periods", str(clock_periods),
        "--duration", repr(excitation_s),
        "--out", str(out / "excitation"),
        *common,
    ]  # fmt: skip
    echo(f"maskless excite {shlex.join(excite_argv)}")
    # The first stage checks the experiment's flags before it simulates anything.
    excitation = excite.run_excitation(_stage_args(excite, excite_argv))
    identify_argv = [
        "--input", excitation["files"]["recording"],
        "--ts", repr(excitation["sample_period_s"]),
        "--orders", str(order),
        "--method", "pem",
        "--out", str(out / "identification"),
    ]  # fmt: skip
    echo(f"maskless identify {shlex.join(identify_argv)}")
    report = identify.run_identification(_stage_args(identify, identify_argv))
    (model,) = report["models"]
    warning = None
    if not model["verdict"].startswith(EXPLAINS_VERDICT):
        warning = (
            "the identified model does not show that the input explains the output, so the "
            "controller designed on it is not to be trusted; excite the slow dynamics more (a "
            "PRBS with longer bits, a larger amplitude or a longer record)"
        )
        echo(f"WARNING: {warning}")
    simulate_argv = [
        "--controller", f"offset-free-lqg:{model['model_file']}",
        "--duration", repr(closed_loop_s),
        "--out", str(out / "closed_loop"),
        *common,
    ]  # fmt: skip
    echo(f"maskless simulate {shlex.join(simulate_argv)}")
    closed_loop = simulate.run_simulation(_stage_args(simulate, simulate_argv))
    return {
        "excitation": excitation,
        "identification": {
            "model_file": model["model_file"],
            "verdict": model["verdict"],
            "warning": warning,
            "dc_gain": model["dc_gain"],
            "poles": model["poles"],
            "validation": model["validation"],
        },
        "closed_loop": closed_loop,
    }


def format_workflow(result: dict) -> str:
    excitation, identified = result["excitation"], result["identification"]
    lines = [
        "",
        f"1. excite: {excitation['signal']}, std {excitation['std_ma']:.2f} mA, crest factor "
        f"{excitation['crest_factor']:.3f}, head {excitation['head_height_mm']['min']:.2f}-"
        f"{excitation['head_height_mm']['max']:.2f} mm",
        f"2. identify: {identified['model_file']}",
        f"   {identified['verdict']}",
    ]
    if identified["warning"]:
        lines.append(f"   WARNING: {identified['warning']}")
    lines.append("3. simulate on the pneumatic plant, controller designed on that model:")
    lines += [f"   {line}" for line in tracking_lines(result["closed_loop"]["tracking"])]
    lines.append(f"   plot {result['closed_loop']['files']['plot']}")
    return "\n".join(lines)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless workflow`."""
    parser.add_argument(
        "--out", type=Path, default=Path("workflow"), metavar="DIR", help="default ./workflow"
    )
    parser.add_argument("--signal", choices=SIGNALS, default="prbs", help="default prbs")
    parser.add_argument(
        "--amplitude", type=float, default=25.0, metavar="MA", help="mA (default 25)"
    )
    parser.add_argument(
        "--offset",
        type=float,
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
    parser.add_argument("--seed", type=int, default=0, metavar="N", help="default 0")
    add_config_argument(parser)
    parser.add_argument("--json", action="store_true", help="print the summaries as one JSON")


def run_command(args: argparse.Namespace) -> int:
    """`maskless workflow`: returns the process exit code."""
    result = run_workflow(
        args.out,
        signal=args.signal,
        amplitude_ma=args.amplitude,
        offset_ma=args.offset,
        clock_periods=args.clock_periods,
        excitation_s=args.excitation_duration,
        order=args.order,
        closed_loop_s=args.duration,
        seed=args.seed,
        config=args.config,
        echo=(lambda line: None) if args.json else print,
    )
    print(json.dumps(result) if args.json else format_workflow(result))
    return 0


def main(argv: list[str] | None = None) -> int:
    """Runs the workflow as a script: `python -m maskless.diagrams.commands.workflow --help`."""
    from maskless.diagrams.cli import main as cli_main

    return cli_main(["workflow", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    raise SystemExit(main())
