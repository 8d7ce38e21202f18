"""maskless: simulate, identify and control a soft-robot head positioner.

The positioner is for mask-free head-and-neck radiotherapy. Each subcommand's --help says more.
"""

import argparse
import contextlib
import importlib
import math
import os
import signal
import sys
import threading
from pathlib import Path

from maskless.errors import MasklessError

# numpy's and scipy's OpenBLAS on one thread, unless the user set it: read when numpy loads, which
# no import above does. maskless's matrices are small (an order-4 N4SID on 100,000 samples takes
# 0.24 s on one thread or two), and the second core is its workers' (plots, the recording),
# where OpenBLAS's idle threads would spin: they took 0.35 of the 1.0 CPU-seconds of `maskless
# identify --no-plots`.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# Command -> (module, summary). A command module has a docstring (its --help), add_arguments and
# run_command; it parses flags into a typed request, makes one library call and formats the
# result. maskless.errors.MasklessError is reported as a one-line message (exit 2), and so is a
# stop by SIGINT or SIGTERM (exit 130 or 143); anything else is a bug and keeps its traceback.
# Only the module of the command being run is imported, so no command's start-up pays for
# another's imports (identification's would add about 0.7 s to the 0.35 s `maskless simulate`
# takes to start).
_COMMANDS = {
    "simulate": (
        "maskless.diagrams.commands.simulate",
        "simulate the closed loop, record it and summarise it",
    ),
    "excite": (
        "maskless.diagrams.commands.excite",
        "drive the plant open loop with an identification signal and record it",
    ),
    "identify": (
        "maskless.diagrams.commands.identify",
        "identify models from a recorded experiment and judge them",
    ),
    "analyze": (
        "maskless.diagrams.commands.analyze",
        "operating range of the plant; stability margins and robustness of the controllers",
    ),
    "montecarlo": (
        "maskless.diagrams.commands.montecarlo",
        "a population of patients through the loop, on every core or a Dask cluster",
    ),
    "workflow": (
        "maskless.diagrams.commands.workflow",
        "excite, identify, design and simulate: the paper's workflow end to end",
    ),
}


def add_config_argument(parser: argparse.ArgumentParser) -> None:
    """The --config flag every simulating or analysing command takes."""
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE.yaml",
        help="YAML overriding the shipped defaults (assets/simulation.yaml); a shipped fault "
        "example is found by its name, e.g. faults/both-cameras-lost.yaml",
    )


def add_preset_argument(parser: argparse.ArgumentParser) -> None:
    """The --preset flag: shipped scenario presets applied before --config."""
    from maskless.diagrams.scenario import scenario_preset_names

    parser.add_argument(
        "--preset",
        action="append",
        default=None,
        metavar="NAME",
        help="a shipped scenario preset applied over the defaults, before --config (repeatable): "
        + ", ".join(scenario_preset_names()),
    )


def add_sensor_arguments(parser: argparse.ArgumentParser) -> None:
    """The --sensors and --image-rate flags of the commands that run the cameras."""
    parser.add_argument(
        "--sensors",
        choices=("model", "rendered"),
        default=None,
        help="model: the cameras' measurement formulas (fast); rendered: Drake renders each "
        "camera's images and a Haar cascade finds the face in them (default: the config's "
        "cameras.NAME.rendering.enabled, model)",
    )
    parser.add_argument(
        "--image-rate",
        type=positive_number,
        default=None,
        metavar="HZ",
        help="rendered camera images per second per camera in the recording (default: the "
        "config's camera_image_rate_hz, 2)",
    )


def given_labels(args: argparse.Namespace, flag_of_field: dict[str, str]) -> dict[str, str]:
    """Field -> flag, for the flags the user actually typed: an error names no other flag."""
    given = getattr(args, "given_flags", frozenset())
    return {field: flag for field, flag in flag_of_field.items() if flag in given}


def positive_number(text: str) -> float:
    """An argparse type: a positive, finite number (in the flag's own unit)."""
    value = finite_number(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a positive number")
    return value


def finite_number(text: str) -> float:
    """An argparse type: a finite number (in the flag's own unit)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number")
    return value


def add_out_argument(parser: argparse.ArgumentParser, default: str, contents: str) -> None:
    """The --out flag: the folder ``contents`` go to, ``./default`` unless given."""
    parser.add_argument(
        "--out",
        type=Path,
        default=Path(default),
        metavar="DIR",
        help=f"where {contents} go (default ./{default})",
    )


def add_overwrite_argument(parser: argparse.ArgumentParser) -> None:
    """The --overwrite flag of the commands whose --out is a run's folder (``RunFolder``)."""
    parser.add_argument(
        "--overwrite",
        action="store_true",
        help="replace the files of a run already in --out (without it, such a folder is refused)",
    )


def scenario_from_flags(args: argparse.Namespace, flag_fields: dict[str, str]):
    """The scenario of ``--config`` with the scenario fields the given flags set.

    Args:
        args: the parsed flags; ``args.config`` names the scenario file (or None), and
            ``args.preset``, where the command has it, the shipped presets applied before it.
        flag_fields: flag -> the scenario field it sets (``{"--duration": "duration_s"}``).
            ``--plant`` and ``--controller`` take their shorthands (``identified:MODEL.yaml``).
            ``args.sensors``, when given, renders every camera or none (``--sensors``).

    Raises:
        ConfigError: naming the file and the flags actually given, and the field at fault.
    """
    from maskless.diagrams.scenario import (
        cameras_measured_by,
        controller_from_shorthand,
        plant_from_shorthand,
        scenario_with_overrides,
    )

    parse = {"--plant": plant_from_shorthand, "--controller": controller_from_shorthand}
    overrides, labels = {}, {}
    for flag, field_name in flag_fields.items():
        value = getattr(args, flag.removeprefix("--").replace("-", "_"))
        if value is None:
            continue
        overrides[field_name] = parse[flag](value) if flag in parse else value
        labels[field_name] = flag
    sensors = getattr(args, "sensors", None)
    presets = getattr(args, "preset", None) or ()
    if sensors is not None:
        # --sensors changes every camera the file (and the other flags) configured.
        cameras = scenario_with_overrides(args.config, overrides, labels, presets).cameras
        overrides["cameras"] = cameras_measured_by(cameras, rendered=sensors == "rendered")
        labels["cameras"] = "--sensors"
    return scenario_with_overrides(args.config, overrides, labels, presets)


def build_parser(argv: list[str]) -> argparse.ArgumentParser:
    """The parser, with full arguments for the command named in ``argv`` (if any)."""
    parser = argparse.ArgumentParser(prog="maskless", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    chosen = next((word for word in argv if not word.startswith("-")), None)
    for name, (module_name, summary) in _COMMANDS.items():
        if name != chosen:
            commands.add_parser(name, help=summary)
            continue
        module = importlib.import_module(module_name)
        command = commands.add_parser(name, help=summary, description=module.__doc__)
        module.add_arguments(command)
        command.set_defaults(module=module)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised as Ctrl-C's KeyboardInterrupt is, so that a command stops the same way."""


def _raise_terminated(signum, frame):
    raise Terminated()


@contextlib.contextmanager
def _sigterm_as_an_exception():
    """SIGTERM raises ``Terminated`` in the block (Python's default would end the process at once).

    Only in the main thread, where Python runs signal handlers; the old handler comes back after.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGTERM, _raise_terminated)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _with_notes(message: str, error: BaseException) -> str:
    """``message`` with the error's notes (what a stopped run left) after it, on one line."""
    return "; ".join([message, *getattr(error, "__notes__", [])])


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `maskless` console script."""
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser(argv).parse_args(argv)
    args.given_flags = frozenset(word.split("=", 1)[0] for word in argv if word.startswith("--"))
    try:
        with _sigterm_as_an_exception():
            return args.module.run_command(args)
    except MasklessError as error:
        print(f"maskless {args.command}: error: {_with_notes(str(error), error)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt as stop:
        # Stopped from outside: one line and the shell's code for the signal, no traceback.
        signum = signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT
        print(
            f"maskless {args.command}: {_with_notes(f'stopped by {signum.name}', stop)}",
            file=sys.stderr,
        )
        return 128 + signum


if __name__ == "__main__":
    sys.exit(main())
