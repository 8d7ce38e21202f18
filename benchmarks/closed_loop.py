"""Closed-loop speed, as simulated seconds per wall second; prints one JSON line.

The figures: the bare closed-loop diagram (no recording) and the whole `maskless simulate` command
(recording, MCAP, plot and summary), in process and as a fresh process (interpreter and imports
included).

Beside them: the bare diagram's speed when built for a sweep (``SWEPT_PARAMETERS`` in the
Context) and with every constant of the pneumatic plant in the Context, and a head-mass sweep
(24 heads of 4-6 kg, one Monte Carlo trial's length each) run by writing each head into one built
diagram's Context (``set_plant_parameters``) and by building a diagram per head, as a sweep did
before. A rebuilt
loop also moves its reference and its filters' start to the new head's rest; the written one keeps
them, so the two sweeps simulate the same time but not the same trajectories.

Targets on a 2-core machine: core diagram >= 1000x real time, whole command >= 300x.
"""

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator

from maskless.diagrams.cli import main as maskless_main
from maskless.diagrams.closed_loop import build_closed_loop, set_plant_parameters
from maskless.diagrams.controller_design import NominalPneumatic
from maskless.diagrams.scenario import load_scenario
from maskless.systems.plant.pneumatic_plant import STEP_PARAMETERS, SWEPT_PARAMETERS

DEFAULT_DURATION_S = 120.0
SWEEP_PARAMETER_SETS = 24
SWEEP_HEAD_MASS_KG = (4.0, 6.0)
# One Monte Carlo trial of benchmarks/accuracy.py: a step at 5 s, then 30 s.
SWEEP_SIMULATED_S = 35.0

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402


def core_real_time_factor(
    duration_s: float, repeats: int, plant_context_parameters=(), supervisor: bool = True
) -> float:
    """Best of ``repeats``: the diagram alone, built once, simulated from a fresh context."""
    config = load_scenario()
    if not supervisor:
        config = dataclasses.replace(
            config, safety=dataclasses.replace(config.safety, enabled=False)
        )
    loop = build_closed_loop(
        config, record=False, plant_context_parameters=plant_context_parameters
    )
    best = float("inf")
    for _ in range(repeats):
        simulator = Simulator(loop.diagram)
        loop.diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(0))
        start = time.perf_counter()
        simulator.Initialize()
        simulator.AdvanceTo(duration_s)
        best = min(best, time.perf_counter() - start)
    return duration_s / best


def _simulate(diagram, duration_s: float, prepare=lambda context: None) -> None:
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(0))
    prepare(context)
    simulator.Initialize()
    simulator.AdvanceTo(duration_s)


def head_mass_sweep(repeats: int) -> dict:
    """Wall time of the sweep (best of ``repeats``, the two ways interleaved) each way."""
    config = load_scenario()
    # Shared by both ways, as benchmarks/accuracy.py shares it: the controller knows the nominal
    # head only.
    nominal = NominalPneumatic.of(config)
    heads = [
        dataclasses.replace(config.pneumatic, head_mass_kg=float(mass))
        for mass in np.linspace(*SWEEP_HEAD_MASS_KG, SWEEP_PARAMETER_SETS)
    ]

    def rebuilding():
        for head in heads:
            head_config = dataclasses.replace(config, pneumatic=head)
            loop = build_closed_loop(head_config, record=False, nominal=nominal)
            _simulate(loop.diagram, SWEEP_SIMULATED_S)

    def one_diagram():
        diagram = build_closed_loop(
            config, record=False, nominal=nominal, plant_context_parameters=SWEPT_PARAMETERS
        ).diagram
        for head in heads:
            _simulate(
                diagram,
                SWEEP_SIMULATED_S,
                lambda context, head=head: set_plant_parameters(diagram, context, head),
            )

    best = {rebuilding: float("inf"), one_diagram: float("inf")}
    for _ in range(repeats):
        for sweep in best:
            start = time.perf_counter()
            sweep()
            best[sweep] = min(best[sweep], time.perf_counter() - start)
    return {
        "parameter_sets": SWEEP_PARAMETER_SETS,
        "head_mass_kg_range": SWEEP_HEAD_MASS_KG,
        "simulated_s_per_set": SWEEP_SIMULATED_S,
        "rebuilding_wall_s": best[rebuilding],
        "one_diagram_wall_s": best[one_diagram],
        "rebuilding_over_one_diagram": best[rebuilding] / best[one_diagram],
    }


def command_real_time_factor(duration_s: float, repeats: int, fresh_process: bool) -> float:
    best = float("inf")
    with tempfile.TemporaryDirectory() as out:
        args = ["simulate", "--duration", str(duration_s), "--out", out, "--overwrite", "--json"]
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
    core = core_real_time_factor(args.duration, args.repeats)
    unsupervised = core_real_time_factor(args.duration, args.repeats, supervisor=False)
    swept = core_real_time_factor(args.duration, args.repeats, SWEPT_PARAMETERS)
    every = core_real_time_factor(args.duration, args.repeats, STEP_PARAMETERS)
    figures = {
        "benchmark": "closed_loop",
        "simulated_s_per_run": args.duration,
        # The default loop compiles every plant constant into its expressions.
        "core_diagram_x_real_time": core,
        # The same loop without the safety supervisor: what the supervisor costs.
        "core_diagram_without_safety_supervisor_x_real_time": unsupervised,
        # Built for a sweep: head mass, stiffness, damping, leak, valve conductances and supply
        # pressure in the Context; and every constant of the step in the Context.
        "core_diagram_swept_constants_in_context_x_real_time": swept,
        "core_diagram_every_plant_constant_in_context_x_real_time": every,
        "swept_over_default_core": swept / core,
        "every_over_default_core": every / core,
        "head_mass_sweep": head_mass_sweep(args.repeats),
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
