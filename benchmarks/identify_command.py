"""Start-up and whole-command time of `maskless identify`, as a user runs it; one JSON line.

- Import: a fresh interpreter importing the command's module (``maskless.diagrams.commands.
  identify``, what the CLI loads to parse the flags, before it forks the plotting worker and then
  imports the estimators), timed inside that process.
- Command: the wall time of the whole `maskless identify` process (interpreter, imports, reading
  the CSV record, the order-2 PEM fit, the report, the model file and the three plots) on a
  generated 20,000-sample CSV record (target <= 1 s, issue 14), and its CPU time (user + system,
  with the plotting child's); then the same with ``--no-plots`` (no plotting process, no
  matplotlib).

Each figure is the median of ``--repeats`` fresh processes, after one run that is not counted (it
warms the disk cache). The record is tests/identification_records.py's order-2 system with
coloured noise, the same as benchmarks/identification.py's PEM figure.
"""

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import maskless

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from identification_records import simulate_record  # noqa: E402
from machine import machine_description  # noqa: E402

SAMPLES = 20_000
COMMAND_MODULE = "maskless.diagrams.commands.identify"
# Prints how long the import took, measured inside the fresh interpreter.
_TIMED_IMPORT = (
    "import time; start = time.perf_counter(); import {module}; print(time.perf_counter() - start)"
)


def write_record(folder: Path) -> tuple[Path, Path]:
    """The input and output CSV files (one value per line) of a seeded order-2 record."""
    u, y, _, _ = simulate_record(2, "coloured", SAMPLES, seed=7)
    paths = folder / "u.csv", folder / "y.csv"
    for path, values in zip(paths, (u, y), strict=True):
        np.savetxt(path, values)
    return paths


def maskless_command() -> list[str]:
    """The `maskless` console script beside this interpreter, or its module where none is."""
    script = Path(sys.executable).with_name("maskless")
    return [str(script)] if script.is_file() else [sys.executable, "-m", "maskless.diagrams.cli"]


def import_seconds() -> float:
    """The command module's import time in a fresh interpreter (s)."""
    code = _TIMED_IMPORT.format(module=COMMAND_MODULE)
    done = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    return float(done.stdout)


def command_seconds(record: tuple[Path, Path], out: Path, plots: bool = True) -> dict:
    """Wall and CPU time of one whole `maskless identify` process, order-2 PEM (s).

    CPU time is user + system over the process and its plotting child: on a shared machine it
    says how much work there was when the wall time says how long someone else's took too.
    """
    u_path, y_path = record
    arguments = ["identify", "--input", str(u_path), "--output", str(y_path), "--ts", "0.048"]
    arguments += ["--orders", "2", "--method", "pem", "--out", str(out)]
    arguments += [] if plots else ["--no-plots"]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    subprocess.run([*maskless_command(), *arguments], check=True, capture_output=True)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return {"wall": wall, "cpu": cpu}


def runs_of(measure, repeats: int) -> list:
    """``repeats`` calls of ``measure()``, after one that is not counted."""
    measure()
    return [measure() for _ in range(repeats)]


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=5, help="fresh processes per figure")
    args = parser.parse_args()
    if args.repeats < 1:
        raise ValueError(f"--repeats {args.repeats}: expected at least 1")
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as folder:
        record = write_record(Path(folder))
        out = Path(folder) / "out"
        commands = runs_of(lambda: command_seconds(record, out), args.repeats)
        unplotted = runs_of(lambda: command_seconds(record, out, plots=False), args.repeats)
    imports = runs_of(import_seconds, args.repeats)
    walls, cpus = [run["wall"] for run in commands], [run["cpu"] for run in commands]
    unplotted_walls = [run["wall"] for run in unplotted]
    figures = {
        "benchmark": "identify_command",
        "samples": SAMPLES,
        "method": "pem",
        "order": 2,
        "command": maskless_command()[-1],
        # The code measured: this checkout's, or another put first on PYTHONPATH.
        "package": str(Path(maskless.__file__).parent),
        "import_seconds": statistics.median(imports),
        "import_seconds_runs": imports,
        "command_seconds": statistics.median(walls),
        "command_seconds_runs": walls,
        "command_cpu_seconds": statistics.median(cpus),
        "command_no_plots_seconds": statistics.median(unplotted_walls),
        "command_no_plots_seconds_runs": unplotted_walls,
        "command_no_plots_cpu_seconds": statistics.median(run["cpu"] for run in unplotted),
        "targets": {"command_seconds": 1.0},
        # The machine may be shared: its 1-minute load average before and after the runs.
        "load_average": [load_before, os.getloadavg()[0]],
        "machine": machine_description(),
    }
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
