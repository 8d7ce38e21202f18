"""Simulating a scenario's closed loop, and what a run gives back.

``simulate(scenario)`` builds the closed loop (``closed_loop.build_closed_loop``), runs it seeded
with the scenario's seed, and returns a ``SimulationRun``: its logged signals by port name, its
metrics, and methods that write its MCAP recording and its plot.
"""

import functools
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator

from maskless.camera_images import CameraFrame
from maskless.diagrams.closed_loop import (
    REFERENCE_NAME,
    ClosedLoop,
    Signal,
    build_closed_loop,
    logged_signals,
    set_plant_parameters,
)
from maskless.diagrams.output_folder import RunFolder, output_file
from maskless.diagrams.run_recording import signal_channels
from maskless.diagrams.run_summary import summarize, summary_with_timing
from maskless.diagrams.scenario import Scenario
from maskless.systems.control.step_reference import set_step_levels
from maskless.systems.plant.pneumatic_physics import PneumaticParameters

# A long run reports progress after each of this many equal chunks.
PROGRESS_CHUNKS = 10
# Runs at least this long report their progress on stderr in ``simulate_to_files``.
_PROGRESS_MIN_DURATION_S = 600.0


@dataclass
class SimulationRun:
    """The outcome of ``simulate``.

    Attributes:
        scenario: what was simulated (its ``duration_s`` and ``random_seed`` as run).
        closed_loop: the built loop: its Diagram, the controller's model and design.
        signals: exported output name -> its logged samples (``head_height_m``,
            ``reference_head_height_m``, ``fusion.estimated_state``, ...).
        wall_time_s: how long the simulation took (s), not counting the build.
        frames: the rendered cameras' recorded images with what was found in them, in time
            order (``scenario.camera_image_rate_hz`` per camera); empty without rendered cameras.
    """

    scenario: Scenario
    closed_loop: ClosedLoop
    signals: dict[str, Signal]
    wall_time_s: float
    frames: list[CameraFrame] = field(default_factory=list)

    @functools.cached_property
    def metrics(self) -> dict:
        """Tracking, estimation and controller figures (mm, mA and s).

        They are what ``maskless simulate --json`` prints, less the timing and the files written.
        """
        return summarize(self)

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        return self.scenario.duration_s / self.wall_time_s

    def recording_channels(self) -> list:
        """The run's logs as the channels of its MCAP recording."""
        return signal_channels(self.signals, self.closed_loop.sensor_names)

    def write_mcap(self, path: str | Path, metadata: dict | None = None) -> Path:
        """Writes the run's recording (topics in ``maskless.recording``) to ``path``.

        ``metadata`` (name -> {key: value}, strings) opens the file (``write_recording``).
        """
        from maskless.recording import write_recording

        path = output_file(path)
        write_recording(path, self.recording_channels(), frames=self.frames, metadata=metadata)
        return path

    def first_and_last_frames(self) -> dict[str, list[CameraFrame]]:
        """Each rendered camera's first and last recorded frame (what frames.png shows)."""
        by_camera: dict[str, list[CameraFrame]] = {}
        for frame in first_and_last_frames(self.frames):
            by_camera.setdefault(frame.camera, []).append(frame)
        return by_camera

    def plot_frames(self, path: str | Path) -> Path:
        """Draws each rendered camera's first and last frame with its boxes to ``path`` (PNG)."""
        from maskless.analysis.camera_frames_plot import plot_camera_frames

        return plot_camera_frames(output_file(path), self.first_and_last_frames())

    def plot_arguments(self, show_tolerance: bool = True) -> dict:
        """``plot_closed_loop``'s keyword arguments, as arrays and strings.

        Arrays and strings pickle, so a worker process can draw them.
        """
        s = self.signals
        return dict(
            times_s=s["head_height_m"].times_s,
            reference_m=s["reference_head_height_m"].values[0],
            head_m=s["head_height_m"].values[0],
            local_tracks_m={
                name: s[f"{name}_filter.estimated_state"].values[0]
                for name in self.closed_loop.sensor_names
            },
            fused_m=s["fusion.estimated_state"].values[0],
            command_times_s=s["inlet_valve_current_a"].times_s,
            command_a=s["inlet_valve_current_a"].values[0],
            outlet_command_a=s["outlet_valve_current_a"].values[0],
            title=f"{self.closed_loop.plant} plant, {self.closed_loop.controller}: head height "
            "and valve commands",
            tolerance_m=self.scenario.metrics.tolerance_m if show_tolerance else None,
        )

    def plot(self, path: str | Path, show_tolerance: bool = True) -> Path:
        """Draws head height, reference, tracks and valve commands to ``path`` (PNG).

        The clinical band about the reference is drawn when ``show_tolerance``.
        """
        from maskless.analysis.closed_loop_plots import plot_closed_loop

        path = output_file(path)
        return plot_closed_loop(path, **self.plot_arguments(show_tolerance))


def simulate(
    scenario: Scenario,
    *,
    record: bool = True,
    progress: Callable[[float, float], None] | None = None,
    on_chunk: Callable[[dict[str, Signal], list[CameraFrame]], None] | None = None,
    nominal=None,
    keep_all_frames: bool = True,
) -> SimulationRun:
    """Builds and simulates ``scenario``'s closed loop.

    It runs for the scenario's ``duration_s``, seeded with its ``random_seed``.

    Args:
        scenario: a validated scenario (``load_scenario``).
        record: log every exported output (False measures the bare diagram).
        progress: called as progress(simulated_s, duration_s) after each chunk of the run.
        on_chunk: called after each chunk with the samples logged and the camera frames recorded
            since the previous call (a recording can be written while the loop runs).
        nominal: ``closed_loop.NominalPneumatic.of(scenario)`` when the caller has it already (a
            Monte Carlo over head masses shares one).
        keep_all_frames: keep every recorded camera frame in the run; False keeps each camera's
            first and last (a caller that streams them with ``on_chunk`` needs no more, and an
            hour's frames would take gigabytes).
    """
    closed_loop = build_closed_loop(scenario, record=record, nominal=nominal)
    return simulate_loop(
        closed_loop,
        scenario,
        progress=progress,
        on_chunk=on_chunk,
        keep_all_frames=keep_all_frames,
    )


def simulate_loop(
    closed_loop: ClosedLoop,
    scenario: Scenario,
    *,
    progress: Callable[[float, float], None] | None = None,
    on_chunk: Callable[[dict[str, Signal], list[CameraFrame]], None] | None = None,
    plant_parameters: PneumaticParameters | None = None,
    reference_levels_m=None,
    keep_all_frames: bool = True,
) -> SimulationRun:
    """Simulates a built loop and collects its logs (see ``simulate`` for the callbacks).

    It runs for ``scenario.duration_s``, seeded with ``scenario.random_seed``. With
    ``plant_parameters``, the pneumatic plant runs with those constants instead of the built ones
    (``closed_loop.set_plant_parameters``; the loop must be built with them as
    ``plant_context_parameters``), and with ``reference_levels_m`` (the start height, then the
    height after each of the loop's steps, m) the reference holds those, so a sweep over patients
    needs one built loop.
    """
    simulator = Simulator(closed_loop.diagram)
    context = simulator.get_mutable_context()
    closed_loop.diagram.SetRandomContext(context, RandomGenerator(scenario.random_seed))
    if plant_parameters is not None:
        set_plant_parameters(closed_loop.diagram, context, plant_parameters)
    if reference_levels_m is not None:
        set_step_levels(closed_loop.diagram, context, REFERENCE_NAME, reference_levels_m)
    frames = closed_loop.frames
    frames.clear()  # a loop simulated again records afresh
    start = time.perf_counter()
    simulator.Initialize()
    chunks = PROGRESS_CHUNKS if progress is not None or on_chunk is not None else 1
    taken: dict = {}  # per log sink, the samples already handed to on_chunk
    frames_taken = 0
    for chunk in range(1, chunks + 1):
        simulator.AdvanceTo(scenario.duration_s * chunk / chunks)
        if progress is not None:
            progress(context.get_time(), scenario.duration_s)
        if on_chunk is not None:
            on_chunk(logged_signals(closed_loop, context, taken), frames[frames_taken:])
        if not keep_all_frames:
            frames[:] = first_and_last_frames(frames)
        frames_taken = len(frames)
    wall_time_s = time.perf_counter() - start
    return SimulationRun(
        scenario, closed_loop, logged_signals(closed_loop, context), wall_time_s, list(frames)
    )


# The files a run (`maskless simulate`, `maskless excite`) may write into its folder.
RUN_FILES = ("run.mcap", "run.png", "frames.png")


def simulate_to_files(scenario: Scenario, out: str | Path, *, overwrite: bool = False) -> dict:
    """Simulates ``scenario``, writing OUT/run.mcap and OUT/run.png (``maskless simulate``).

    With rendered cameras, the recording holds their images too and OUT/frames.png shows each
    camera's first and last recorded frame. The recording is written while the loop runs, the
    plots after. Runs of 10 minutes or more report progress on stderr.

    OUT is claimed before anything is simulated (``output_folder.RunFolder``): it is refused
    when another run is writing it, or, unless ``overwrite``, when it holds a run's files. The
    files are written as run.partial.mcap, ... and renamed when the run succeeds. A run that
    raises (the CLI turns SIGINT and SIGTERM into KeyboardInterrupt) or whose process is killed
    leaves run.partial.mcap finished with its footer and marked as cut.

    Returns:
        The run's metrics with its timing and the files written (``files``).

    Raises:
        ConfigError: OUT refused, naming it or the file in the way.
    """
    with RunFolder(out, RUN_FILES, overwrite=overwrite) as folder:
        summary = _simulate_into(scenario, folder)
    summary["files"] = folder.final_paths(summary["files"])
    return summary


def _simulate_into(scenario: Scenario, folder: RunFolder) -> dict:
    """``simulate_to_files``'s run, into ``folder``'s temporaries; ``files`` by final name."""
    from maskless.analysis.camera_frames_plot import plot_camera_frames
    from maskless.analysis.closed_loop_plots import plot_closed_loop
    from maskless.diagrams.background import Worker
    from maskless.diagrams.plot_worker import start_plot_worker
    from maskless.recording import write_recording_batches

    def report_progress(simulated_s, duration_s):
        print(f"simulated {simulated_s:.0f} / {duration_s:.0f} s", file=sys.stderr, flush=True)

    mcap_path, png_path = folder.temporary("run.mcap"), folder.temporary("run.png")
    camera_names = list(scenario.cameras)
    rendered = rendered_camera_names(scenario)
    # The second core works while the loop runs: one worker writes the recording as the samples
    # come in, another imports matplotlib and then plots.
    recorder = Worker(f"writing {mcap_path}", write_recording_batches, mcap_path, rendered)
    plotter = start_plot_worker(png_path)
    long_run = scenario.duration_s >= _PROGRESS_MIN_DURATION_S
    try:
        run = simulate(
            scenario,
            progress=report_progress if long_run else None,
            on_chunk=lambda signals, frames: recorder.send(
                (signal_channels(signals, camera_names), frames)
            ),
            keep_all_frames=False,
        )
        plotter.send((plot_closed_loop, (png_path,), run.plot_arguments()))
        files = {"recording": "run.mcap", "plot": "run.png"}
        if rendered:
            frames_path = folder.temporary("frames.png")
            plotter.send((plot_camera_frames, (frames_path, run.first_and_last_frames()), {}))
            files["frames"] = "frames.png"
        summary = summary_with_timing(run)
        recorder.wait()
        plotter.wait()
    except BaseException:
        # Stopped or failed: the recording so far is finished with its footer, and no worker
        # outlives the run.
        recorder.stop()
        plotter.stop()
        raise
    summary["files"] = files
    return summary


def first_and_last_frames(frames: list[CameraFrame]) -> list[CameraFrame]:
    """Each camera's first and last frame of ``frames`` (once if it has one), in time order."""
    first: dict[str, CameraFrame] = {}
    last: dict[str, CameraFrame] = {}
    for frame in frames:
        first.setdefault(frame.camera, frame)
        last[frame.camera] = frame
    kept = {id(frame): frame for frame in [*first.values(), *last.values()]}
    return sorted(kept.values(), key=lambda frame: frame.time_s)


def rendered_camera_names(scenario: Scenario) -> list[str]:
    """The scenario's cameras that are rendered, in order."""
    return [name for name, camera in scenario.cameras.items() if camera.rendering.enabled]
