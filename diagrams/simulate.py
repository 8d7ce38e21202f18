"""Simulate the paper's closed loop: record it to MCAP, plot it and summarise it.

Runs the whole sensing and control chain of the seed paper (two depth cameras, local Kalman
filters, track-to-track fusion, LQG, valves, bladder and head) as one Drake Diagram for
--duration simulated seconds, then writes DIR/run.mcap and DIR/run.png and prints a summary.
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

from maskless.analysis.metrics import estimate_error_std_m, tracking_metrics
from maskless.analysis.plots import plot_closed_loop
from maskless.analysis.recording import (
    COMMAND_TOPIC,
    FUSION_TOPIC,
    HEAD_POSITION_TOPIC,
    REFERENCE_TOPIC,
    Channel,
    filter_estimate_topic,
    sensor_measurement_topic,
    write_recording,
)
from maskless.assets.loader import ConfigError
from maskless.diagrams.closed_loop import ClosedLoop, build_paper_closed_loop
from maskless.diagrams.config import (
    SimulationConfig,
    load_simulation_config,
    validate_simulation_config,
)
from maskless.systems.lqg_controller import closed_loop_poles
from maskless.systems.units import a_to_ma, m_to_mm

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
) -> SimulationRun:
    """Builds and simulates the closed loop for ``config.duration_s``, seeded with
    ``config.random_seed``.

    Args:
        config: a validated configuration.
        record: log every recorded signal (False measures the bare diagram).
        progress: called as progress(simulated_s, duration_s) between chunks of a long run.
    """
    closed_loop = build_paper_closed_loop(config, record=record)
    simulator = Simulator(closed_loop.diagram)
    context = simulator.get_mutable_context()
    closed_loop.diagram.SetRandomContext(context, RandomGenerator(config.random_seed))
    start = time.perf_counter()
    simulator.Initialize()
    chunks = _PROGRESS_CHUNKS if progress is not None else 1
    for chunk in range(1, chunks + 1):
        simulator.AdvanceTo(config.duration_s * chunk / chunks)
        if progress is not None:
            progress(context.get_time(), config.duration_s)
    wall_time_s = time.perf_counter() - start
    signals = {}
    for name, sink in closed_loop.loggers.items():
        log = sink.FindLog(context)
        signals[name] = Signal(log.sample_times().copy(), log.data().copy())
    return SimulationRun(config, closed_loop, signals, wall_time_s)


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
    s = run.signals
    channels = [
        Channel(
            REFERENCE_TOPIC,
            _nanoseconds(s["reference"].times_s),
            {"reference_m": s["reference"].values[0]},
        ),
        Channel(
            HEAD_POSITION_TOPIC,
            _nanoseconds(s["head_height"].times_s),
            {"head_position_m": s["head_height"].values[0]},
        ),
    ]
    for name in run.closed_loop.sensor_names:
        distance, valid = s[f"{name}.distance_m"], s[f"{name}.valid"]
        channels.append(
            Channel(
                sensor_measurement_topic(name),
                _nanoseconds(distance.times_s),
                {"distance_m": distance.values[0], "valid": valid.values[0] > 0.5},
            )
        )
    for name in run.closed_loop.sensor_names:
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
            _nanoseconds(s["command"].times_s),
            {"current_a": s["command"].values[0]},
        )
    )
    return channels


def summarize(run: SimulationRun) -> dict:
    """The run's figures as a JSON-ready dict (mm, mA and s, what people read)."""
    config, loop, s = run.config, run.closed_loop, run.signals
    times = s["head_height"].times_s
    head, reference = s["head_height"].values[0], s["reference"].values[0]
    steps = [t for t in config.reference.step_times_s if t <= times[-1]]
    metrics = tracking_metrics(
        times,
        head,
        reference,
        last_step_time_s=steps[-1] if steps else 0.0,
        tolerance_m=config.metrics.tolerance_m,
        unsettled_evaluation_delay_s=config.metrics.unsettled_evaluation_delay_s,
    )
    # Estimates are judged once the filters have forgotten their initial guess, whatever the head.
    start = min(config.metrics.estimation_start_s, float(times[-1]) / 2)
    estimation = {"evaluation_start_s": start}
    for name in loop.sensor_names:
        track = s[f"{name}_filter.estimated_state"].values[0]
        estimation[f"{name}_error_std_mm"] = m_to_mm(
            estimate_error_std_m(times, track, head, start)
        )
        estimation[f"{name}_valid_fraction"] = float(np.mean(s[f"{name}.valid"].values[0] > 0.5))
    fused = s["fusion.estimated_state"].values[0]
    estimation["fused_error_std_mm"] = m_to_mm(estimate_error_std_m(times, fused, head, start))
    estimation["fused_error_mean_mm"] = m_to_mm(
        float(np.mean(fused[times >= start] - head[times >= start]))
    )

    model, design, paper = loop.model, loop.design, config.paper
    # The model's output is a distance below the camera; the head rises as it shrinks.
    lift_gain_mm_per_ma = -m_to_mm(model.dc_gain_m_per_a()) / a_to_ma(1.0)
    lift_limits = [
        lift_gain_mm_per_ma * (current - paper.operating_current_ma)
        for current in (0.0, paper.valve_saturation_current_ma)
    ]
    poles = closed_loop_poles(model, design)
    command = s["command"].values[0]

    def tracking_mm(value):
        return None if value is None else m_to_mm(value)

    return {
        "plant": "paper",
        "controller": "paper-lqg",
        "duration_s": config.duration_s,
        "random_seed": config.random_seed,
        "tracking": {
            "tolerance_mm": m_to_mm(config.metrics.tolerance_m),
            "settled": metrics.settled,
            "settle_time_s": metrics.settle_time_s,
            "evaluation_start_s": metrics.evaluation_start_s,
            "rms_error_mm": m_to_mm(metrics.rms_error_m),
            "p95_abs_error_mm": m_to_mm(metrics.p95_abs_error_m),
            "max_abs_error_mm": m_to_mm(metrics.max_abs_error_m),
            "overshoot_mm": tracking_mm(metrics.overshoot_m),
            "final_error_mm": m_to_mm(metrics.final_error_m),
            "head_travel_mm": m_to_mm(float(head.max() - head.min())),
            "reference_travel_mm": m_to_mm(float(reference.max() - reference.min())),
        },
        "estimation": estimation,
        "paper_model": {
            "lift_gain_mm_per_ma": lift_gain_mm_per_ma,
            "steady_lift_range_mm": sorted(lift_limits),
            "lqr_gain_ma_per_mm": (design.K[0] * a_to_ma(1.0) / m_to_mm(1.0)).tolist(),
            "open_loop_pole_magnitudes": np.abs(poles["open_loop"]).tolist(),
            "regulator_pole_magnitudes": np.abs(poles["regulator"]).tolist(),
            "estimator_pole_magnitudes": np.abs(poles["estimator"]).tolist(),
            "command_range_ma": [a_to_ma(float(command.min())), a_to_ma(float(command.max()))],
            "operating_current_ma": paper.operating_current_ma,
        },
        "timing": {
            "wall_time_s": run.wall_time_s,
            "real_time_factor": config.duration_s / run.wall_time_s,
        },
    }


def _format_optional(value, unit, digits=2):
    return "never" if value is None else f"{value:.{digits}f} {unit}"


def format_summary(summary: dict) -> str:
    """The summary as lines a person reads."""
    t, e, p = summary["tracking"], summary["estimation"], summary["paper_model"]
    band = t["tolerance_mm"]
    settle = (
        f"settled within ±{band:g} mm after {t['settle_time_s']:.2f} s"
        if t["settled"]
        else f"did NOT settle within ±{band:g} mm; errors below from "
        f"t = {t['evaluation_start_s']:.1f} s"
    )
    lines = [
        f"maskless simulate: plant '{summary['plant']}', controller '{summary['controller']}', "
        f"{summary['duration_s']:g} s simulated, seed {summary['random_seed']}",
        "",
        "Tracking (true head height vs reference)",
        f"  {settle}",
        f"  RMS {t['rms_error_mm']:.3f} mm, p95 {t['p95_abs_error_mm']:.3f} mm, "
        f"max {t['max_abs_error_mm']:.3f} mm, final {t['final_error_mm']:+.3f} mm",
        f"  overshoot {_format_optional(t['overshoot_mm'], 'mm', 3)}; the reference moved "
        f"{t['reference_travel_mm']:.2f} mm, the head {t['head_travel_mm']:.4f} mm",
        "",
        f"Estimation (estimate - true head height, std, from t = {e['evaluation_start_s']:.0f} s)",
    ]
    for key, value in e.items():
        if key.endswith("_error_std_mm"):
            name = key.removesuffix("_error_std_mm")
            valid = e.get(f"{name}_valid_fraction")
            extra = f" ({100 * valid:.2f} % valid frames)" if valid is not None else ""
            lines.append(f"  {name:<10} {value:.3f} mm{extra}")
    lines.append(f"  fused mean error {e['fused_error_mean_mm']:+.3f} mm")
    lo, hi = p["steady_lift_range_mm"]
    lines += [
        "",
        "Why the paper's loop cannot track (its own model, Eq. 26)",
        f"  steady-state lift {p['lift_gain_mm_per_ma']:.3e} mm/mA: the whole valve range "
        f"(0-165 mA) holds the head between {lo:+.4f} and {hi:+.4f} mm of its start",
        f"  LQR gain K = [{p['lqr_gain_ma_per_mm'][0]:.4f}, "
        f"{p['lqr_gain_ma_per_mm'][1]:.4f}] mA/mm; "
        f"pole magnitudes open loop {_poles(p['open_loop_pole_magnitudes'])}, "
        f"with LQR {_poles(p['regulator_pole_magnitudes'])}",
        f"  command stayed in [{p['command_range_ma'][0]:.3f}, {p['command_range_ma'][1]:.3f}] mA "
        f"around the operating point {p['operating_current_ma']:.2f} mA",
        "",
        f"Wall time {summary['timing']['wall_time_s']:.3f} s "
        f"({summary['timing']['real_time_factor']:.0f}x real time)",
    ]
    if "files" in summary:
        lines += ["Files:"] + [f"  {kind}: {path}" for kind, path in summary["files"].items()]
    return "\n".join(lines)


def _poles(magnitudes) -> str:
    return "[" + ", ".join(f"{m:.6f}" for m in magnitudes) + "]"


def plot_run(run: SimulationRun, path: Path) -> Path:
    """The run's plot (see ``plot_closed_loop``)."""
    s = run.signals
    return plot_closed_loop(
        path,
        times_s=s["head_height"].times_s,
        reference_m=s["reference"].values[0],
        head_m=s["head_height"].values[0],
        local_tracks_m={
            name: s[f"{name}_filter.estimated_state"].values[0]
            for name in run.closed_loop.sensor_names
        },
        fused_m=s["fusion.estimated_state"].values[0],
        command_times_s=s["command"].times_s,
        command_a=s["command"].values[0],
        title="paper plant, paper LQG: head height and valve command",
        tolerance_m=run.config.metrics.tolerance_m,
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
    parser.add_argument(
        "--config",
        type=Path,
        default=None,
        metavar="FILE.yaml",
        help="YAML overriding the shipped defaults (assets/simulation.yaml)",
    )
    parser.add_argument(
        "--json", action="store_true", help="print the summary as one JSON object instead of text"
    )


def run_command(args: argparse.Namespace) -> int:
    """`maskless simulate`: returns the process exit code."""
    config = load_simulation_config(args.config)
    if args.duration is not None:
        config.duration_s = args.duration
    if args.seed is not None:
        config.random_seed = args.seed
    try:
        validate_simulation_config(config)
    except ConfigError as error:
        raise ConfigError(f"command line (--duration/--seed): {error}") from error

    def report_progress(simulated_s, duration_s):
        print(f"simulated {simulated_s:.0f} / {duration_s:.0f} s", file=sys.stderr, flush=True)

    long_run = config.duration_s >= _PROGRESS_MIN_DURATION_S
    run = run_closed_loop(config, progress=report_progress if long_run else None)
    summary = summarize(run)
    args.out.mkdir(parents=True, exist_ok=True)
    mcap_path = args.out / "run.mcap"
    write_recording(mcap_path, recording_channels(run))
    png_path = plot_run(run, args.out / "run.png")
    summary["files"] = {"recording": str(mcap_path), "plot": str(png_path)}
    print(json.dumps(summary) if args.json else format_summary(summary))
    return 0
