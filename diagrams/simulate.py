"""Simulate the closed loop: record it to MCAP, plot it and summarise it.

Runs the whole sensing and control chain (two depth cameras, local Kalman filters, track-to-track
fusion, a controller, two valves, bladder and head) as one Drake Diagram for --duration simulated
seconds, then writes DIR/run.mcap and DIR/run.png and prints a summary. By default the plant is the
first-principles pneumatic robot and the controller the offset-free LQG; `--plant paper
--controller paper-lqg` reproduces the seed paper's loop.
"""

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator

from maskless.analysis.plots import plot_closed_loop, prepare_plotting
from maskless.analysis.recording import (
    COMMAND_TOPIC,
    FUSION_TOPIC,
    HEAD_POSITION_TOPIC,
    REFERENCE_TOPIC,
    Channel,
    filter_estimate_topic,
    sensor_measurement_topic,
    write_recording_batches,
)
from maskless.analysis.summary import format_summary, summarize
from maskless.assets.loader import ConfigError
from maskless.diagrams.background import Worker, serve_calls
from maskless.diagrams.cli import add_config_argument
from maskless.diagrams.closed_loop import ClosedLoop, build_closed_loop, set_plant_parameters
from maskless.diagrams.config import SimulationConfig, load_config_with_overrides
from maskless.systems.pneumatic_physics import PneumaticParameters

# What `maskless simulate` reports as a message rather than a traceback.
USER_ERRORS = (ConfigError, FileNotFoundError)

# Long runs report progress this often (fraction of the duration), on stderr.
_PROGRESS_CHUNKS = 10
_PROGRESS_MIN_DURATION_S = 600.0


@dataclass
class Signal:
    """A logged signal: sample times (s) and values (rows = components)."""

    times_s: np.ndarray
    values: np.ndarray


@dataclass
class SimulationRun:
    """The outcome of ``run_closed_loop``."""

    config: SimulationConfig
    closed_loop: ClosedLoop
    signals: dict[str, Signal]
    wall_time_s: float

    @property
    def duration_s(self) -> float:
        return self.config.duration_s


def run_closed_loop(
    config: SimulationConfig,
    *,
    record: bool = True,
    progress: Callable[[float, float], None] | None = None,
    on_chunk: Callable[[dict[str, Signal]], None] | None = None,
    nominal=None,
) -> SimulationRun:
    """Builds and simulates the closed loop for ``config.duration_s``, seeded with
    ``config.random_seed``.

    Args:
        config: a validated configuration.
        record: log every recorded signal (False measures the bare diagram).
        progress: called as progress(simulated_s, duration_s) between chunks of a long run.
        on_chunk: called between chunks with the samples logged since the previous call.
        nominal: passed to ``build_closed_loop``.
    """
    closed_loop = build_closed_loop(config, record=record, nominal=nominal)
    return simulate_loop(closed_loop, config, progress=progress, on_chunk=on_chunk)


def simulate_loop(
    closed_loop: ClosedLoop,
    config: SimulationConfig,
    *,
    progress: Callable[[float, float], None] | None = None,
    on_chunk: Callable[[dict[str, Signal]], None] | None = None,
    plant_parameters: PneumaticParameters | None = None,
) -> SimulationRun:
    """Simulates a built loop for ``config.duration_s``, seeded with ``config.random_seed``, and
    collects its logs (see ``run_closed_loop`` for the callbacks); with ``plant_parameters``, the
    pneumatic plant runs with those constants (``set_plant_parameters``), not the built ones."""
    simulator = Simulator(closed_loop.diagram)
    context = simulator.get_mutable_context()
    closed_loop.diagram.SetRandomContext(context, RandomGenerator(config.random_seed))
    if plant_parameters is not None:
        set_plant_parameters(closed_loop.diagram, context, plant_parameters)
    start = time.perf_counter()
    simulator.Initialize()
    chunks = _PROGRESS_CHUNKS if progress is not None or on_chunk is not None else 1
    taken: dict = {}  # per log sink, the samples already handed to on_chunk
    for chunk in range(1, chunks + 1):
        simulator.AdvanceTo(config.duration_s * chunk / chunks)
        if progress is not None:
            progress(context.get_time(), config.duration_s)
        if on_chunk is not None:
            on_chunk(_logged_signals(closed_loop, context, taken))
    wall_time_s = time.perf_counter() - start
    signals = _logged_signals(closed_loop, context)
    return SimulationRun(config, closed_loop, signals, wall_time_s)


def _logged_signals(closed_loop: ClosedLoop, context, taken: dict | None = None):
    """Every logged signal; with ``taken`` (log sink -> samples already taken, updated here), only
    the samples logged since."""
    taken = {} if taken is None else taken
    first = {sink: taken.get(sink, 0) for sink, _ in closed_loop.loggers.values()}
    signals = {}
    for name, (sink, rows) in closed_loop.loggers.items():
        log = sink.FindLog(context)
        start = first[sink]
        signals[name] = Signal(log.sample_times()[start:].copy(), log.data()[rows, start:].copy())
        taken[sink] = log.num_samples()
    return signals


def _nanoseconds(times_s: np.ndarray) -> np.ndarray:
    return np.round(times_s * 1e9).astype(np.int64)


def _estimate_channel(topic: str, state: Signal, covariance: Signal) -> Channel:
    return Channel(
        topic,
        _nanoseconds(state.times_s),
        {
            "position_m": state.values[0],
            "velocity_m_s": state.values[1],
            "covariance": covariance.values.T.reshape(-1, 2, 2),
        },
    )


def recording_channels(run: SimulationRun) -> list[Channel]:
    """The run's logs as MCAP channels (the topics of the recording format)."""
    return signal_channels(run.signals, run.closed_loop.sensor_names)


def signal_channels(s: dict[str, Signal], sensor_names: list[str]) -> list[Channel]:
    """Logged signals (a whole run's or a chunk's) as MCAP channels."""
    channels = [
        Channel(
            REFERENCE_TOPIC,
            _nanoseconds(s["reference_head_height_m"].times_s),
            {"reference_m": s["reference_head_height_m"].values[0]},
        ),
        Channel(
            HEAD_POSITION_TOPIC,
            _nanoseconds(s["head_height_m"].times_s),
            {"head_position_m": s["head_height_m"].values[0]},
        ),
    ]
    for name in sensor_names:
        distance, valid = s[f"{name}.distance_m"], s[f"{name}.valid"]
        channels.append(
            Channel(
                sensor_measurement_topic(name),
                _nanoseconds(distance.times_s),
                {"distance_m": distance.values[0], "valid": valid.values[0] > 0.5},
            )
        )
    for name in sensor_names:
        channels.append(
            _estimate_channel(
                filter_estimate_topic(name),
                s[f"{name}_filter.estimated_state"],
                s[f"{name}_filter.covariance"],
            )
        )
    channels.append(
        _estimate_channel(FUSION_TOPIC, s["fusion.estimated_state"], s["fusion.covariance"])
    )
    channels.append(
        Channel(
            COMMAND_TOPIC,
            _nanoseconds(s["inlet_valve_current_a"].times_s),
            {
                "current_a": s["inlet_valve_current_a"].values[0],
                "outlet_current_a": s["outlet_valve_current_a"].values[0],
            },
        )
    )
    return channels


def plot_run(run: SimulationRun, path: Path, show_tolerance: bool = True) -> Path:
    """The run's plot (see ``plot_closed_loop``), with the clinical band about the reference
    when ``show_tolerance``."""
    return plot_closed_loop(path, **plot_arguments(run, show_tolerance))


def plot_arguments(run: SimulationRun, show_tolerance: bool = True) -> dict:
    """``plot_closed_loop``'s keyword arguments for the run: arrays and strings, which pickle."""
    s = run.signals
    return dict(
        times_s=s["head_height_m"].times_s,
        reference_m=s["reference_head_height_m"].values[0],
        head_m=s["head_height_m"].values[0],
        local_tracks_m={
            name: s[f"{name}_filter.estimated_state"].values[0]
            for name in run.closed_loop.sensor_names
        },
        fused_m=s["fusion.estimated_state"].values[0],
        command_times_s=s["inlet_valve_current_a"].times_s,
        command_a=s["inlet_valve_current_a"].values[0],
        outlet_command_a=s["outlet_valve_current_a"].values[0],
        title=f"{run.closed_loop.plant} plant, {run.closed_loop.controller}: head height and "
        "valve commands",
        tolerance_m=run.config.metrics.tolerance_m if show_tolerance else None,
    )


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The flags of `maskless simulate`."""
    parser.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated seconds (default: the config's duration_s, 120)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="N",
        help="random seed (default: the config's random_seed, 0)",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out"),
        metavar="DIR",
        help="where run.mcap and run.png go (default: ./out)",
    )
    add_config_argument(parser)
    parser.add_argument(
        "--plant",
        default=None,
        metavar="PLANT",
        help="pneumatic (the first-principles robot), paper (Eq. 25-26) or identified:MODEL.yaml "
        "(a model `maskless identify` wrote, output the head height); default: the config's, "
        "pneumatic",
    )
    parser.add_argument(
        "--controller",
        default=None,
        metavar="CONTROLLER",
        help="offset-free-lqg (designed on the plant), offset-free-lqg:MODEL.yaml (designed on an "
        "identified model) or paper-lqg (the paper's gains); default: the config's, "
        "offset-free-lqg",
    )
    parser.add_argument(
        "--json", action="store_true", help="print the summary as one JSON object instead of text"
    )


def run_command(args: argparse.Namespace) -> int:
    """`maskless simulate`: returns the process exit code."""
    summary = run_simulation(args)
    print(json.dumps(summary) if args.json else format_summary(summary))
    return 0


def run_simulation(args: argparse.Namespace) -> dict:
    """Runs, records and plots the simulation ``args`` describe; returns the summary."""
    config = load_config_with_overrides(
        args.config,
        {
            "--duration": ("duration_s", args.duration),
            "--seed": ("random_seed", args.seed),
            "--plant": ("plant", args.plant),
            "--controller": ("controller", args.controller),
        },
    )

    def report_progress(simulated_s, duration_s):
        print(f"simulated {simulated_s:.0f} / {duration_s:.0f} s", file=sys.stderr, flush=True)

    args.out.mkdir(parents=True, exist_ok=True)
    mcap_path, png_path = args.out / "run.mcap", args.out / "run.png"
    sensor_names = list(config.sensors())
    # The second core works while the loop runs: one worker writes the recording as the samples
    # come in, another imports matplotlib and then plots.
    recorder = Worker(f"writing {mcap_path}", write_recording_batches, mcap_path)
    plotter = Worker(f"plotting {png_path}", serve_calls, prepare_plotting)

    def record(signals):
        recorder.send(signal_channels(signals, sensor_names))

    long_run = config.duration_s >= _PROGRESS_MIN_DURATION_S
    run = run_closed_loop(
        config, progress=report_progress if long_run else None, on_chunk=record
    )
    plotter.send((plot_closed_loop, (png_path,), plot_arguments(run)))
    summary = summarize(run)
    recorder.wait()
    plotter.wait()
    summary["files"] = {"recording": str(mcap_path), "plot": str(png_path)}
    return summary
