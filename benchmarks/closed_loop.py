"""Closed-loop speed: simulated seconds per wall second for the bare paper closed-loop diagram (no
recording) and for the whole `maskless simulate` command (recording, MCAP, plot and summary), in
process and as a fresh process (interpreter and imports included). Prints one JSON line.

Targets on a 2-core machine: core diagram >= 1000x real time, whole command >= 300x.
"""

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator

from maskless.diagrams.cli import main as maskless_main
from maskless.diagrams.closed_loop import build_closed_loop
from maskless.diagrams.scenario import load_scenario

DEFAULT_DURATION_S = 120.0

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402


def core_real_time_factor(duration_s: float, repeats: int) -> float:
    """Best of ``repeats``: the diagram alone, built once, simulated from a fresh context."""
    config = load_scenario()
    loop = build_closed_loop(config, record=False)
    best = float("inf")
    for _ in range(repeats):
        simulator = Simulator(loop.diagram)
        loop.diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(0))
        start = time.perf_counter()
        simulator.Initialize()
        simulator.AdvanceTo(duration_s)
        best = min(best, time.perf_counter() - start)
    return duration_s / best


def command_real_time_factor(duration_s: float, repeats: int, fresh_process: bool) -> float:
    best = float("inf")
    with tempfile.TemporaryDirectory() as out:
        args = ["simulate", "--duration", str(duration_s), "--out", out, "--json"]
        for _ in range(repeats):
            start = time.perf_counter()
            if fresh_process:
                subprocess.run(
                    [sys.executable, "-m", "maskless.diagrams.cli", *args],
                    check=True,
                    capture_output=True,
                )
            else:
                with open("/dev/null", "w") as sink:
                    stdout, sys.stdout = sys.stdout, sink
                    try:
                        maskless_main(args)
                    finally:
                        sys.stdout = stdout
            best = min(best, time.perf_counter() - start)
    return duration_s / best


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration", type=float, default=600.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure; the best counts")
    args = parser.parse_args()
    if not args.duration > 0 or args.repeats < 1:
        raise ValueError(
            f"--duration {args.duration} and --repeats {args.repeats} must be positive"
        )
    figures = {
        "benchmark": "closed_loop",
        "simulated_s_per_run": args.duration,
        "core_diagram_x_real_time": core_real_time_factor(args.duration, args.repeats),
        "whole_command_in_process_x_real_time": command_real_time_factor(
            args.duration, args.repeats, fresh_process=False
        ),
        "whole_command_fresh_process_x_real_time": command_real_time_factor(
            args.duration, args.repeats, fresh_process=True
        ),
        # What a user sees from `maskless simulate` with no flags: interpreter start and imports
        # (about a second) weigh heavily on a 120 s run.
        "default_command_fresh_process_x_real_time": command_real_time_factor(
            DEFAULT_DURATION_S, args.repeats, fresh_process=True
        ),
        "targets": {"core_diagram_x_real_time": 1000, "whole_command_x_real_time": 300},
        "machine": machine_description(),
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
