"""Injected faults: each kind against its definition, refused when malformed, and in the loop."""

import dataclasses

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial
from scipy import stats

from maskless.diagrams.closed_loop import build_closed_loop
from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from maskless.systems.config_loading import asset_path
from maskless.systems.fault_injection import (
    FaultConfig,
    add_camera_faults,
    add_valve_faults,
    camera_faults_of,
    validate_faults,
)
from maskless.systems.named_symbolic_system import PortMap

PERIOD_S = 0.1
START_S, DURATION_S = 1.0, 2.0


def fault(kind, **fields) -> FaultConfig:
    target = "" if kind.endswith("_stuck") else "kinect_v1"
    return FaultConfig(kind=kind, target=target, start_s=START_S, duration_s=DURATION_S, **fields)


def run_camera(faults, frames=50, valid=1.0, seed=0):
    """The fault system alone on a camera whose distance ramps 1 mm per frame from 0.8 m.

    Returns the frame times and the (distance, valid) the filter would read at each.
    """
    builder = DiagramBuilder()
    times = [0.0, 100.0]
    ramp = PiecewisePolynomial.FirstOrderHold(
        times, np.array([[0.8, 0.8 + 100.0 / PERIOD_S * 1e-3]])
    )
    camera = PortMap(
        outputs={
            "distance_m": builder.AddSystem(TrajectorySource(ramp)).get_output_port(),
            "valid": builder.AddSystem(ConstantVectorSource([valid])).get_output_port(),
        }
    )
    ports = add_camera_faults(builder, "kinect_v1", faults, camera, PERIOD_S)
    logs = {}
    for port in ("distance_m", "valid"):
        logs[port] = builder.AddSystem(VectorLogSink(1, PERIOD_S))
        builder.Connect(ports.outputs[port], logs[port].get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    simulator.AdvanceTo((frames - 0.5) * PERIOD_S)
    context = simulator.get_context()
    log = logs["distance_m"].FindLog(context)
    return log.sample_times(), log.data()[0], logs["valid"].FindLog(context).data()[0]


def in_window(times):
    return (times >= START_S) & (times < START_S + DURATION_S)


def ramp_at(times):
    return 0.8 + times / PERIOD_S * 1e-3


def test_a_dead_camera_delivers_nothing_in_its_window_only():
    times, distance, valid = run_camera([fault("camera_dead")])
    inside = in_window(times)
    assert np.all(distance[inside] == 0) and np.all(valid[inside] == 0)
    np.testing.assert_allclose(distance[~inside], ramp_at(times[~inside]), atol=1e-12)
    assert np.all(valid[~inside] == 1)


def test_a_frozen_camera_repeats_its_last_frame_before_the_fault_as_valid():
    times, distance, valid = run_camera([fault("camera_frozen")])
    inside = in_window(times)
    last_before = ramp_at(times[np.flatnonzero(inside)[0] - 1])
    np.testing.assert_allclose(distance[inside], last_before, atol=1e-12)
    assert np.all(valid[inside] == 1)
    np.testing.assert_allclose(distance[~inside], ramp_at(times[~inside]), atol=1e-12)


def test_a_bias_is_added_to_valid_frames_in_its_window():
    times, distance, _ = run_camera([fault("camera_bias", bias_m=0.02)])
    expected = ramp_at(times) + np.where(in_window(times), 0.02, 0.0)
    np.testing.assert_allclose(distance, expected, atol=1e-12)
    _, invalid_distance, _ = run_camera([fault("camera_bias", bias_m=0.02)], valid=0.0)
    np.testing.assert_allclose(invalid_distance, ramp_at(times), atol=1e-12)  # no bias added


def test_a_non_finite_camera_reads_nan_marked_valid():
    times, distance, valid = run_camera([fault("camera_non_finite")])
    inside = in_window(times)
    assert np.all(np.isnan(distance[inside])) and np.all(valid[inside] == 1)
    assert np.all(np.isfinite(distance[~inside]))


def test_dropouts_lose_frames_at_their_probability_in_their_window_and_are_seeded():
    burst = FaultConfig("camera_dropouts", "kinect_v1", 0.0, 1e6, probability=0.3)
    times, _, valid = run_camera([burst], frames=4000)
    lost = int(np.sum(valid == 0))
    assert stats.binomtest(lost, valid.size, 0.3).pvalue > 0.01
    assert np.array_equal(
        run_camera([burst], frames=200, seed=4)[2], run_camera([burst], 200, seed=4)[2]
    )
    assert not np.array_equal(
        run_camera([burst], 200, seed=4)[2], run_camera([burst], 200, seed=5)[2]
    )
    _, _, valid = run_camera([fault("camera_dropouts", probability=1.0)])
    assert np.all(valid[in_window(times[: valid.size])] == 0)


def test_overlapping_faults_act_in_the_order_they_are_named():
    times, distance, valid = run_camera([fault("camera_bias", bias_m=0.02), fault("camera_dead")])
    assert np.all(valid[in_window(times)] == 0)
    times, distance, valid = run_camera([fault("camera_dead"), fault("camera_bias", bias_m=0.02)])
    assert np.all(distance[in_window(times)] == 0)  # a dead frame is not valid: no bias on it


def test_a_stuck_valve_sees_its_stuck_current_in_its_window():
    builder = DiagramBuilder()
    command = builder.AddSystem(ConstantVectorSource([0.09])).get_output_port()
    faults = {"stuck": fault("inlet_stuck", current_a=0.165)}
    seen = add_valve_faults(builder, faults, "inlet", command)
    assert add_valve_faults(builder, faults, "outlet", command) is command  # no outlet fault
    log = builder.AddSystem(VectorLogSink(1, PERIOD_S))
    builder.Connect(seen, log.get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(4.0)
    found = log.FindLog(simulator.get_context())
    expected = np.where(in_window(found.sample_times()), 0.165, 0.09)
    np.testing.assert_array_equal(found.data()[0], expected)


@pytest.mark.parametrize(
    "changes, message",
    [
        (dict(kind="camera_exploded"), "faults.f.kind = camera_exploded: expected one of"),
        (dict(target="kinect_v9"), "faults.f.target = kinect_v9: expected a camera"),
        (dict(start_s=-1.0), "faults.f.start_s = -1.0"),
        (dict(duration_s=0.0), "faults.f.duration_s = 0.0: expected a positive duration"),
        (dict(bias_m=0.01), "faults.f.bias_m = 0.01: expected 0: camera_dead does not use it"),
        (dict(kind="camera_dropouts", probability=1.5), "faults.f.probability = 1.5"),
        (dict(kind="inlet_stuck", target=""), "faults.f.current_a"),
        (dict(kind="inlet_stuck", current_a=0.1), "faults.f.target = kinect_v1: expected nothing"),
    ],
)
def test_a_malformed_fault_is_refused_naming_its_field(changes, message):
    broken = dataclasses.replace(fault("camera_dead"), **changes)
    if broken.kind == "inlet_stuck" and "current_a" not in changes:
        broken.current_a = -0.1
    with pytest.raises(ConfigError, match=message):
        validate_faults({"f": broken}, ["kinect_v1", "kinect_v2"])


def test_a_fault_that_starts_after_the_run_changes_nothing(tmp_path):
    """Not a draw of any other source moves: the dropouts' RandomSource is added last."""
    plain = simulate(load_scenario(duration_s=12.0))
    late = {
        "late": FaultConfig("camera_dropouts", "kinect_v2", 50.0, 10.0, probability=0.5),
        "later": FaultConfig("camera_bias", "kinect_v1", 50.0, 10.0, bias_m=0.01),
    }
    faulted = simulate(load_scenario(duration_s=12.0, faults=late))
    for name, signal in plain.signals.items():
        np.testing.assert_array_equal(faulted.signals[name].values, signal.values, err_msg=name)


def test_both_cameras_dead_leave_the_loop_blind_and_stuck_valves_move_the_head():
    """Today's loop has no detection (issue 13): what the faults do, measured."""
    dead = {
        name: FaultConfig("camera_dead", name, 20.0, 100.0) for name in ("kinect_v1", "kinect_v2")
    }
    run = simulate(load_scenario(duration_s=60.0, faults=dead))
    covariance = run.signals["fusion.covariance"]
    after = covariance.times_s >= 20.0
    assert np.all(np.diff(covariance.values[0][after]) > 0)  # the fused variance only grows
    valid = run.signals["kinect_v1.valid"]
    assert np.all(valid.values[0][valid.times_s >= 20.2] == 0)
    # An inlet stuck open is fought with the outlet; with the outlet stuck shut too, nothing can.
    open_inlet = FaultConfig("inlet_stuck", "", 20.0, 100.0, current_a=0.165)
    fought = simulate(load_scenario(duration_s=60.0, faults={"open": open_inlet}))
    outlet = fought.signals["outlet_valve_current_a"]
    before, after = outlet.values[0][outlet.times_s < 20.0], outlet.values[0][outlet.times_s > 30.0]
    assert after.mean() > before.mean() + 0.01  # A: the outlet opens to drain what leaks in
    shut_outlet = FaultConfig("outlet_stuck", "", 20.0, 100.0, current_a=0.0)
    lost = simulate(
        load_scenario(duration_s=60.0, faults={"open": open_inlet, "shut": shut_outlet})
    )
    reference = lost.signals["reference_head_height_m"].values[0][-1]
    assert lost.signals["head_height_m"].values[0][-1] - reference > 0.005


def test_the_controllers_design_never_sees_a_fault():
    plain = build_closed_loop(load_scenario(), record=False)
    faults = {
        "stuck": FaultConfig("outlet_stuck", "", 0.0, 100.0, current_a=0.0),
        "bias": FaultConfig("camera_bias", "kinect_v1", 0.0, 100.0, bias_m=0.03),
    }
    faulted = build_closed_loop(load_scenario(faults=faults), record=False)
    for name in ("K", "M", "augmented_A", "augmented_B", "state_per_reference"):
        np.testing.assert_array_equal(getattr(faulted.design, name), getattr(plain.design, name))
    assert camera_faults_of(faults, "kinect_v1") == [faults["bias"]]


@pytest.mark.parametrize(
    "example", sorted(p.name for p in asset_path("simulation.yaml").parent.glob("faults/*.yaml"))
)
def test_each_shipped_fault_example_loads_and_its_faults_start_at_30_s(example):
    scenario = load_scenario(asset_path(f"faults/{example}"))
    assert scenario.faults and all(f.start_s == 30.0 for f in scenario.faults.values())
