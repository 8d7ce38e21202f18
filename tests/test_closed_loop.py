"""The closed-loop Diagram: its names, its recording read by mcap's own reader, Eq. 10, seeds."""

import dataclasses
import json

import numpy as np
import pytest
from mcap.reader import make_reader
from pydrake.systems.analysis import Simulator
from pydrake.systems.primitives import Demultiplexer

from maskless.diagrams.closed_loop import (
    build_closed_loop,
    set_plant_parameters,
    set_safety_reset,
)
from maskless.diagrams.controller_design import NominalPneumatic
from maskless.diagrams.run_recording import signal_channels
from maskless.diagrams.scenario import (
    controller_from_shorthand,
    load_scenario,
    plant_from_shorthand,
)
from maskless.diagrams.simulation import simulate, simulate_loop
from maskless.errors import ConfigError
from maskless.recording import read_recording, write_recording
from maskless.systems.fault_injection import FaultConfig
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import SWEPT_PARAMETERS, equilibrium_state

TOPICS = {
    "/reference",
    "/plant/head_height",
    "/controller/command",
    "/fusion/estimate",
    "/sensors/kinect_v1/measurement",
    "/sensors/kinect_v2/measurement",
    "/filters/kinect_v1/estimate",
    "/filters/kinect_v2/estimate",
    "/safety/status",
    "/plant/bladder_pressure",
}


@pytest.mark.parametrize(
    "plant, controller, diagram_name, own_systems",
    [
        (
            "paper",
            "paper-lqg",
            "paper_paper_lqg_closed_loop",
            {"paper_lqg", "valve_current_limits", "paper_plant"},
        ),
        (
            "pneumatic",
            "offset-free-lqg",
            "pneumatic_offset_free_lqg_closed_loop",
            {"offset_free_lqg", "pneumatic_plant"},
        ),
        (
            "pneumatic",
            "paper-lqg",
            "pneumatic_paper_lqg_closed_loop",
            {"paper_lqg", "pneumatic_plant", "outlet_valve_shut"},
        ),
        (
            "paper",
            "offset-free-lqg",
            "paper_offset_free_lqg_closed_loop",
            {"offset_free_lqg", "paper_plant"},
        ),
    ],
)
def test_diagram_names_its_subsystems_and_exports_named_outputs(
    config, plant, controller, diagram_name, own_systems
):
    config.plant = plant_from_shorthand(plant)
    config.controller = controller_from_shorthand(controller)
    loop = build_closed_loop(config, record=False)
    diagram = loop.diagram
    assert diagram.get_name() == diagram_name
    names = {system.get_name() for system in diagram.GetSystems()}
    assert (
        own_systems
        | {
            "reference",
            # The cameras and their filters, each kind one bank (add_symbolic_banks).
            "kinect_v1+kinect_v2",
            "kinect_v1_filter+kinect_v2_filter",
            "kinect_v1.noise",
            "kinect_v2.noise",
            "fusion",
        }
        <= names
    )
    sizes = {
        diagram.get_output_port(i).get_name(): diagram.get_output_port(i).size()
        for i in range(diagram.num_output_ports())
    }
    assert sizes["head_height_m"] == 1 and sizes["inlet_valve_current_a"] == 1
    assert sizes["outlet_valve_current_a"] == 1
    assert sizes["fusion.estimated_state"] == 2
    # A camera's measurement and a filter's track are exported only when logged.
    assert not any(name.startswith("kinect_") for name in sizes)
    logged = ("kinect_v1.distance_m", "kinect_v1.valid", "kinect_v2_filter.covariance")
    diagram = build_closed_loop(config, record=logged).diagram
    sizes = {
        diagram.get_output_port(i).get_name(): diagram.get_output_port(i).size()
        for i in range(diagram.num_output_ports())
    }
    assert sizes["kinect_v2_filter.covariance"] == 4
    assert sizes["kinect_v1.distance_m"] == 1 and sizes["kinect_v1.valid"] == 1
    assert "kinect_v2.distance_m" not in sizes


def test_a_loop_that_logs_no_camera_has_no_system_only_to_name_their_outputs():
    # Measured: each Demultiplexer costs a step its cache work whether it is read or not.
    diagram = build_closed_loop(load_scenario(), record=("head_height_m",)).diagram
    demultiplexers = {
        system.get_name() for system in diagram.GetSystems() if isinstance(system, Demultiplexer)
    }
    assert not {name for name in demultiplexers if name.startswith("kinect_")}
    assert "bladder_gauge_pressure" not in {system.get_name() for system in diagram.GetSystems()}


def test_recording_read_back_with_the_mcap_reader(short_run, tmp_path):
    path = tmp_path / "run.mcap"
    write_recording(path, short_run.recording_channels())
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        topics = {channel.topic for channel in summary.channels.values()}
        encodings = {schema.encoding for schema in summary.schemas.values()}
        counts = {}
        for _, channel, message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            assert channel.message_encoding == "json"
            json.loads(message.data)
    assert topics == TOPICS and encodings == {"jsonschema"}
    # The controller period (1/15 s) and the 15 Hz frames set the message counts.
    period_s = short_run.closed_loop.model.sample_period_s
    duration_s = short_run.scenario.duration_s
    assert counts["/plant/head_height"] == pytest.approx(duration_s / period_s, abs=2)
    assert counts["/sensors/kinect_v1/measurement"] == pytest.approx(duration_s * 15, abs=2)


def test_fused_messages_are_eq_10_of_the_local_estimates_with_the_same_stamp(short_run, tmp_path):
    path = tmp_path / "run.mcap"
    write_recording(path, short_run.recording_channels())
    recording = read_recording(path)
    by_time = {
        topic: {t: payload for t, payload in recording.messages[topic]}
        for topic in (
            "/filters/kinect_v1/estimate",
            "/filters/kinect_v2/estimate",
            "/fusion/estimate",
        )
    }
    assert by_time["/fusion/estimate"].keys() == by_time["/filters/kinect_v1/estimate"].keys()
    for stamp, fused in list(by_time["/fusion/estimate"].items())[::50]:
        informations, weighted = [], []
        for topic in ("/filters/kinect_v1/estimate", "/filters/kinect_v2/estimate"):
            local = by_time[topic][stamp]
            Y = np.linalg.inv(np.array(local["covariance"]))
            informations.append(Y)
            weighted.append(Y @ [local["head_height_m"], local["head_velocity_m_s"]])
        P_F = np.linalg.inv(sum(informations))
        np.testing.assert_allclose(
            [fused["head_height_m"], fused["head_velocity_m_s"]], P_F @ sum(weighted), rtol=1e-9
        )
        np.testing.assert_allclose(fused["covariance"], P_F, rtol=1e-8)


def run_bytes(config, seed, tmp_path):
    config.duration_s = 5.0
    config.random_seed = seed
    tmp_path.mkdir(exist_ok=True)
    path = tmp_path / f"seed{seed}.mcap"
    write_recording(path, simulate(config).recording_channels())
    return path.read_bytes()


def test_same_seed_same_recording_bit_for_bit(config, tmp_path):
    first = run_bytes(config, 3, tmp_path / "first")
    assert run_bytes(config, 3, tmp_path / "second") == first
    assert run_bytes(config, 4, tmp_path) != first


def test_dropped_and_invalid_frames_never_reach_the_estimate(config):
    config.duration_s = 10.0
    config.cameras["kinect_v1"].dropout_probability = 0.4
    config.cameras["kinect_v2"].dropout_probability = 0.4
    run = simulate(config)
    valid = run.signals["kinect_v1.valid"].values[0]
    assert 0.5 < np.mean(valid) < 0.7
    fused = run.signals["fusion.estimated_state"].values
    head = run.signals["head_height_m"].values[0]
    assert np.all(np.isfinite(fused))
    # Zeros would read as a head 0.9-1.04 m up; the estimate stays within millimetres of truth.
    assert np.max(np.abs(fused[0] - head)) < 0.01


def test_a_head_written_into_a_built_loop_starts_at_its_own_rest(config):
    config.duration_s = 5.0
    loop = build_closed_loop(config, plant_context_parameters=SWEPT_PARAMETERS)
    built = simulate_loop(loop, config).signals
    same = simulate_loop(loop, config, plant_parameters=config.pneumatic).signals
    for name, signal in built.items():
        np.testing.assert_array_equal(same[name].values, signal.values, err_msg=name)
    heavier = dataclasses.replace(config.pneumatic, head_mass_kg=6.0)
    heads = simulate_loop(loop, config, plant_parameters=heavier).signals["head_height_m"]
    currents = NominalPneumatic.of(config).allocation.currents(config.start_lift_m)
    rest = equilibrium_state(heavier, *map(float, currents))[LIFT]
    assert heads.values[0, 0] == pytest.approx(heavier.rest_head_height_m + rest, abs=1e-12)
    start_gap, end_gap = heads.values[0, [0, -1]] - built["head_height_m"].values[0, [0, -1]]
    assert start_gap < -2e-3
    # The reference and the filters keep the built start: the loop lifts the heavier head to it.
    assert start_gap < 2 * end_gap < 0


def test_plant_parameters_need_the_pneumatic_plant(paper_config):
    loop = build_closed_loop(paper_config, record=False)
    context = loop.diagram.CreateDefaultContext()
    with pytest.raises(ValueError, match="no 'pneumatic_plant'"):
        set_plant_parameters(loop.diagram, context, paper_config.pneumatic)


def test_the_default_loop_compiles_its_constants_and_says_so(config):
    # Built without context parameters (the default), a head mass cannot be written: the error
    # names the constant and the value it was compiled with.
    config.duration_s = 1.0
    loop = build_closed_loop(config, record=False)
    heavier = dataclasses.replace(config.pneumatic, head_mass_kg=6.0)
    with pytest.raises(ConfigError, match="head_mass_kg"):
        simulate_loop(loop, config, plant_parameters=heavier)


def test_the_patients_motion_is_in_the_head_height_the_cameras_see_and_the_log_holds(config):
    # A fast drift, and too short a run for the bladder to answer it: the logged head height
    # is the bladder's (the same run without motion) plus the drift.
    config.duration_s = 0.2
    still = simulate(config).signals["head_height_m"]
    config.patient_motion.enabled = True
    config.patient_motion.drift_rate_m_per_s = 0.01
    config.patient_motion.shift_rate_per_s = 0.0
    config.patient_motion.breathing_amplitude_m = 0.0
    moving = simulate(config).signals["head_height_m"]
    np.testing.assert_allclose(moving.values[0] - still.values[0], 0.01 * moving.times_s, atol=5e-5)


def test_the_supervisor_passes_a_healthy_loop_unchanged(config):
    """The loop with its supervisor moves the head exactly as the loop without one."""
    unsupervised = dataclasses.replace(
        config, safety=dataclasses.replace(config.safety, enabled=False), duration_s=30.0
    )
    bare = simulate(unsupervised).signals
    supervised = simulate(dataclasses.replace(config, duration_s=30.0)).signals
    assert "safety.beam_hold" not in bare
    for name in ("head_height_m", "inlet_valve_current_a", "fusion.estimated_state"):
        np.testing.assert_array_equal(supervised[name].values, bare[name].values, err_msg=name)
    np.testing.assert_array_equal(
        supervised["safety.inlet_valve_current_a"].values, bare["inlet_valve_current_a"].values
    )
    assert not supervised["safety.reasons"].values.any()


def test_both_cameras_lost_reach_the_safe_state_within_half_a_second_and_hold_the_head(
    config, tmp_path
):
    """The issue's target: the safe state within 0.5 s, the head within 2 mm of where it was."""
    start_s = 20.0
    lost = {
        name: FaultConfig("camera_dead", name, start_s, 100.0)
        for name in ("kinect_v1", "kinect_v2")
    }
    run = simulate(dataclasses.replace(config, duration_s=60.0, faults=lost))
    safety = run.metrics["safety"]
    first = safety["events"][0]
    assert first["action"] == "hold" and first["first_s"] - start_s <= 0.5
    s = run.signals
    times, head = s["head_height_m"].times_s, s["head_height_m"].values[0]
    at_start = head[np.searchsorted(times, start_s)]
    assert np.max(np.abs(head[times >= start_s] - at_start)) <= 0.002
    beam = s["safety.beam_hold"]
    assert np.all(beam.values[0][beam.times_s >= first["first_s"]] == 1.0)
    assert safety["beam_on_while_off_target_s"] == 0.0
    # The recording says so at the same tick.
    path = tmp_path / "lost.mcap"
    write_recording(path, signal_channels(run.signals, run.closed_loop.sensor_names))
    times_ns, states = read_recording(path).topic_arrays("/safety/status", "state")
    assert states[0] == "normal"
    first_holding = times_ns[np.flatnonzero(states == "holding")[0]]
    assert first_holding == round(first["first_s"] * 1e9)
    _, reasons = read_recording(path).topic_arrays("/safety/status", "reasons")
    assert first["reason"] in reasons[-1].split(",")


def test_a_latched_fault_waits_for_a_reset_and_the_loop_resumes_after_it(config):
    """Both cameras lost for 3 s: the supervisor holds until a person resets it."""
    lost = {
        name: FaultConfig("camera_dead", name, 20.0, 3.0) for name in ("kinect_v1", "kinect_v2")
    }
    loop = build_closed_loop(dataclasses.replace(config, faults=lost), record=("safety.mode",))
    simulator = Simulator(loop.diagram)
    context = simulator.get_mutable_context()
    mode = loop.diagram.GetOutputPort("safety.mode")
    simulator.AdvanceTo(30.0)  # the cameras are back since 23 s: still holding
    assert mode.Eval(context)[0] == 1.0
    set_safety_reset(loop.diagram, context, True)
    simulator.AdvanceTo(30.1)
    set_safety_reset(loop.diagram, context, False)
    simulator.AdvanceTo(31.0)
    assert mode.Eval(context)[0] == 0.0
    reasons = loop.diagram.GetOutputPort("safety.reasons").Eval(context)
    assert not reasons.any()
