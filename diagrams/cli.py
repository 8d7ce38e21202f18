"""maskless: simulate, identify and control a soft-robot head positioner for mask-free head-and-neck
radiotherapy. Each subcommand's --help says more."""

import argparse
import sys

from maskless.analysis.identification_data import RecordError
from maskless.assets.loader import ConfigError
from maskless.diagrams import identify, simulate


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="maskless", description=__doc__)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    # Each command module has a docstring (its --help), add_arguments and run_command.
    for name, module, summary in (
        ("simulate", simulate, "simulate the closed loop, record it and summarise it"),
        ("identify", identify, "identify models from a recorded experiment and judge them"),
    ):
        command = commands.add_parser(name, help=summary, description=module.__doc__)
        module.add_arguments(command)
        command.set_defaults(handler=module.run_command)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `maskless` console script."""
    args = build_parser().parse_args(argv)
    try:
        return args.handler(args)
    except (ConfigError, RecordError, FileNotFoundError) as error:
        print(f"maskless {args.command}: error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
