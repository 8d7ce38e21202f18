"""The rendered cameras: speed, detection, the measurement they give, and the loop they close.

Prints one JSON line (with the machine it ran on). Sections, each selectable with --only:

- speed: per camera, the steady cost of a frame (colour render, depth render, face and eye search
  near the last face, noise on the region and its depth), as frames per second.
- detection: 60 s with the head swept over its working lift (0-18 mm) and back, open loop: the
  fraction of frames with a face, and the frames where a missed face still produced a number
  (must be 0).
- still: the head held still for --still-s seconds: each camera's raw measurement (its
  ``distance_m`` on valid frames) as std and variance, its autocorrelation time (the lag where the
  sample autocorrelation first drops below 1/e) and its bias against the true camera-to-face
  distance, beside the paper's measured variances (22.7 / 11.5 mm^2) and the per-pixel formulas.
- regions: the still head's raw measurement read in other regions by other statistics (the eye
  band's interquartile mean, which the sensor uses; the face box's interquartile mean, mean and
  median; the face box's centre pixel), each frame's depth noise drawn afresh.
- loop: `maskless simulate --sensors rendered` in process (recording and frames.png included):
  real-time factor, beside the model-sensor loop.
- accuracy: --seeds seeds of the default 120 s scenario (5 mm step at 10 s), rendered and model
  cameras: p95 |head - reference| over a fixed window from 20 s after the step to the end.

Targets (issue 11): detection >= 95 % with 0 numbers from missed faces; render + detect >= 30
frames/s per camera; rendered loop >= 1x real time (aim 2x); rendered p95 <= 1 mm.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Multiplexer, TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial

from maskless.diagrams.scenario import cameras_measured_by, load_scenario
from maskless.diagrams.simulation import simulate, simulate_to_files
from maskless.systems.sensing.camera_scene import add_camera_scene
from maskless.systems.sensing.depth_image_noise import kinect_depth_image
from maskless.systems.sensing.depth_sensor import kinect_v1_noise_std_m, kinect_v2_noise_std_m
from maskless.systems.sensing.face_detection import (
    FaceFinder,
    find_face_region,
    region_distance_m,
    scale_box,
)
from maskless.systems.sensing.rendered_depth_sensor import (
    add_rendered_depth_sensor,
    add_rgbd_sensor,
)
from maskless.systems.units import m_to_mm

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

SECTIONS = ("speed", "detection", "still", "regions", "loop", "accuracy")
WORKING_LIFT_M = 0.018  # `maskless analyze operating-range`: the inlet spans 0-18.11 mm
FORMULAS = {"kinect_v1": kinect_v1_noise_std_m, "kinect_v2": kinect_v2_noise_std_m}


def rendered_scenario(**overrides):
    scenario = load_scenario(**overrides)
    scenario.cameras = cameras_measured_by(scenario.cameras, rendered=True)
    return scenario


def run_cameras(
    scenario, heights: PiecewisePolynomial, duration_s: float, seed: int = 0, warm_up_s: float = 0.0
):
    """The rendered cameras watching a head that follows ``heights``: every frame's measurement.

    The wall time counts from ``warm_up_s`` on (the renderer's first frames set it up).
    """
    builder = DiagramBuilder()
    head = builder.AddSystem(TrajectorySource(heights))
    scene = add_camera_scene(builder, head.get_output_port())
    measured = []
    logs = {}
    for name, camera in scenario.cameras.items():
        ports = add_rendered_depth_sensor(
            builder,
            name,
            camera,
            scene,
            lambda camera, t, rgb, measurement: measured.append((camera, t, measurement)),
            1,
        )
        log = builder.AddSystem(VectorLogSink(2, 1.0 / camera.frame_rate_hz))
        mux = builder.AddSystem(Multiplexer(2))
        builder.Connect(ports.outputs["distance_m"], mux.get_input_port(0))
        builder.Connect(ports.outputs["valid"], mux.get_input_port(1))
        builder.Connect(mux.get_output_port(), log.get_input_port())
        logs[name] = log
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(seed))
    simulator.AdvanceTo(warm_up_s)
    start = time.perf_counter()
    simulator.AdvanceTo(duration_s)
    wall_s = time.perf_counter() - start
    ports = {name: log.FindLog(context).data() for name, log in logs.items()}
    return measured, ports, wall_s


def speed(scenario) -> dict:
    """Frames per second per camera, from a 10 s run of each camera alone, head still."""
    height = scenario.pneumatic.rest_head_height_m + scenario.start_lift_m
    result = {}
    for name in scenario.cameras:
        alone = rendered_scenario()
        alone.cameras = {name: alone.cameras[name]}
        warm_up_s, duration_s = 1.0, 11.0
        measured, _, wall_s = run_cameras(alone, _constant(height), duration_s, 0, warm_up_s)
        frames = sum(t > warm_up_s for _, t, _ in measured)
        result[name] = {
            "frames": frames,
            "frames_per_s": frames / wall_s,
            "ms_per_frame": 1e3 * wall_s / frames,
        }
    return result


def _constant(height_m: float) -> PiecewisePolynomial:
    return PiecewisePolynomial.ZeroOrderHold([0.0, 1e9], np.array([[height_m, height_m]]))


def detection(scenario, duration_s: float = 60.0) -> dict:
    """Detection over the working lift, swept up and back down, open loop."""
    rest = scenario.pneumatic.rest_head_height_m
    heights = PiecewisePolynomial.FirstOrderHold(
        [0.0, duration_s / 2, duration_s],
        np.array([[rest, rest + WORKING_LIFT_M, rest]]),
    )
    measured, ports, wall_s = run_cameras(scenario, heights, duration_s)
    result = {"duration_s": duration_s, "wall_s": wall_s}
    for name, camera in scenario.cameras.items():
        frames = [(t, m) for camera_name, t, m in measured if camera_name == name]
        taken = [m for _, m in frames if m.reason != "frame dropped"]
        faces = sum(m.face_box is not None for m in taken)
        # A face found in the wrong place would read a wrong distance: every number against truth.
        errors = [
            m.distance_m - (camera.mount_height_m - heights.value(t)[0, 0])
            for t, m in frames
            if m.valid
        ]
        distance, valid = ports[name]
        result[name] = {
            "frames": len(frames),
            "dropped_frames": len(frames) - len(taken),
            "face_found_fraction": faces / len(taken),
            "both_eyes_found_fraction": sum(len(m.eye_boxes) == 2 for m in taken) / len(taken),
            "valid_fraction": sum(m.valid for _, m in frames) / len(frames),
            "numbers_from_missed_faces": sum(m.face_box is None and m.valid for _, m in frames),
            "port_numbers_while_invalid": int(np.count_nonzero(distance[valid < 0.5])),
            "max_abs_error_mm": float(m_to_mm(np.max(np.abs(errors)))),
        }
    return result


def autocorrelation_time_s(values: np.ndarray, period_s: float) -> float | None:
    """The first lag (s) at which the sample autocorrelation drops below 1/e."""
    centred = values - values.mean()
    if not np.any(centred):
        return None
    acf = np.correlate(centred, centred, mode="full")[centred.size - 1 :]
    acf = acf / acf[0]
    below = np.flatnonzero(acf < np.exp(-1.0))
    return float(below[0] * period_s) if below.size else None


def still(scenario, duration_s: float, seed: int) -> dict:
    """The raw measurement of each camera with the head held still."""
    height = scenario.pneumatic.rest_head_height_m + scenario.start_lift_m
    measured, ports, _ = run_cameras(scenario, _constant(height), duration_s, seed)
    result = {"duration_s": duration_s, "head_height_m": height}
    for name, camera in scenario.cameras.items():
        distance, valid = ports[name]
        values = distance[valid > 0.5]
        true_m = camera.mount_height_m - height
        formula_std_m = FORMULAS[camera.model](true_m, camera.incidence_angle_rad)
        result[name] = {
            "true_distance_mm": m_to_mm(true_m),
            "std_mm": m_to_mm(values.std()),
            "variance_mm2": m_to_mm(m_to_mm(values.var())),
            "bias_mm": m_to_mm(values.mean() - true_m),
            "autocorrelation_time_s": autocorrelation_time_s(values, 1.0 / camera.frame_rate_hz),
            "valid_fraction": float(valid.mean()),
            "paper_variance_mm2": getattr(scenario.paper, f"measured_noise_{camera.model}_mm2"),
            "per_pixel_formula_variance_mm2": m_to_mm(m_to_mm(formula_std_m**2)),
        }
    return result


def _of_valid(statistic):
    """``statistic`` of a region's valid (non-zero) depths; NaN when there are none."""
    return lambda depth: statistic(depth[depth > 0]) if np.any(depth > 0) else np.nan


REGION_READINGS = {
    "eye_band_interquartile_mean": ("eyes", region_distance_m),
    "face_box_interquartile_mean": ("face", region_distance_m),
    "face_box_mean": ("face", _of_valid(np.mean)),
    "face_box_median": ("face", _of_valid(np.median)),
    "face_box_centre_pixel": ("centre", _of_valid(np.mean)),
}


def regions(scenario, frames: int, seed: int) -> dict:
    """Bias and variance of the still head's measurement for each region and statistic."""
    height = scenario.pneumatic.rest_head_height_m + scenario.start_lift_m
    builder = DiagramBuilder()
    head = builder.AddSystem(TrajectorySource(_constant(height)))
    scene = add_camera_scene(builder, head.get_output_port())
    sensors = {}
    for name, camera in scenario.cameras.items():
        sensors[name] = add_rgbd_sensor(builder, name, scene, camera)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    rng = np.random.default_rng(seed)
    result = {}
    for name, camera in scenario.cameras.items():
        sensor_context = sensors[name].GetMyContextFromRoot(context)
        rgb = sensors[name].color_image_output_port().Eval(sensor_context).data
        depth = sensors[name].depth_image_32F_output_port().Eval(sensor_context).data[:, :, 0]
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGBA2GRAY)
        scale = camera.rendering.color_scale
        found = find_face_region(FaceFinder(), gray, None)
        x, y, w, h = scale_box(found.face_box, 1 / scale, depth.shape)
        boxes = {
            "eyes": scale_box(found.region_box, 1 / scale, depth.shape),
            "face": (x, y, w, h),
            "centre": (x + w // 2, y + h // 2, 1, 1),
        }
        true_m = camera.mount_height_m - height
        result[name] = {}
        for reading, (box_name, statistic) in REGION_READINGS.items():
            bx, by, bw, bh = boxes[box_name]
            exact = depth[by : by + bh, bx : bx + bw]
            values = np.array(
                [statistic(kinect_depth_image(exact, camera, 0.0, rng)) for _ in range(frames)],
                dtype=np.float64,
            )
            values = values[np.isfinite(values)]
            result[name][reading] = {
                "bias_mm": float(m_to_mm(values.mean() - true_m)),
                "variance_mm2": float(m_to_mm(m_to_mm(values.var()))),
                "pixels": bw * bh,
            }
    return result


def loop(duration_s: float) -> dict:
    """The rendered closed loop as `maskless simulate --sensors rendered` runs it, and the model."""
    result = {}
    for label, rendered in (("rendered", True), ("model", False)):
        scenario = load_scenario(duration_s=duration_s)
        scenario.cameras = cameras_measured_by(scenario.cameras, rendered=rendered)
        with tempfile.TemporaryDirectory() as out:
            start = time.perf_counter()
            summary = simulate_to_files(scenario, out)
            wall_s = time.perf_counter() - start
        result[label] = {
            "real_time_factor_with_files": duration_s / wall_s,
            "real_time_factor_simulation": summary["timing"]["real_time_factor"],
        }
    return result


def accuracy(seeds: int) -> dict:
    """Tracking over `maskless simulate`'s window (20 s after the step on), per seed.

    p95 |head - reference| and the time within 1 mm as the run's summary reports them, and the
    mean error over the same window.
    """
    result = {}
    for label, rendered in (("rendered", True), ("model", False)):
        p95, within, mean = [], [], []
        for seed in range(seeds):
            scenario = load_scenario(random_seed=seed)
            scenario.cameras = cameras_measured_by(scenario.cameras, rendered=rendered)
            run = simulate(scenario)
            tracking = run.metrics["tracking"]
            p95.append(tracking["p95_abs_error_mm"])
            within.append(tracking["time_within_tolerance_fraction"])
            head = run.signals["head_height_m"]
            error = head.values[0] - run.signals["reference_head_height_m"].values[0]
            mean.append(float(m_to_mm(error[head.times_s >= tracking["window_s"][0]].mean())))
        result[label] = {
            "p95_mm": p95,
            "worst_p95_mm": max(p95),
            "time_within_tolerance_fraction": within,
            "mean_error_mm": mean,
        }
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--only", nargs="+", choices=SECTIONS, default=SECTIONS)
    parser.add_argument("--still-s", type=float, default=120.0, help="still-head seconds")
    parser.add_argument("--loop-s", type=float, default=30.0, help="closed-loop seconds")
    parser.add_argument("--seeds", type=int, default=5, help="accuracy seeds")
    parser.add_argument("--region-frames", type=int, default=300, help="frames per region")
    args = parser.parse_args()
    scenario = rendered_scenario()
    figures = {"machine": machine_description()}
    if "speed" in args.only:
        figures["speed"] = speed(scenario)
    if "detection" in args.only:
        figures["detection"] = detection(scenario)
    if "still" in args.only:
        figures["still"] = still(scenario, args.still_s, seed=1)
    if "regions" in args.only:
        figures["regions"] = regions(scenario, frames=args.region_frames, seed=2)
    if "loop" in args.only:
        figures["loop"] = loop(args.loop_s)
    if "accuracy" in args.only:
        figures["accuracy"] = accuracy(args.seeds)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
