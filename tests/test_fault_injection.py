"""Injected faults: each kind against its definition, refused when malformed, and in the loop."""

import dataclasses

import numpy as np
import pytest
from pydrake.common import RandomGenerator
from pydrake.symbolic import Variable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Demultiplexer,
    TrajectorySource,
    VectorLogSink,
    ZeroOrderHold,
)
from pydrake.trajectories import PiecewisePolynomial
from scipy import stats

from maskless.diagrams.closed_loop import build_closed_loop
from maskless.diagrams.scenario import PaperPlant, load_scenario
from maskless.diagrams.simulation import simulate
from maskless.errors import ConfigError
from maskless.systems.config_loading import asset_path
from maskless.systems.fault_injection import (
    CAMERA_FAULTS,
    FaultConfig,
    add_camera_faults,
    add_controller_faults,
    add_valve_faults,
    camera_faults_of,
    plant_fault_factors,
    validate_faults,
)
from maskless.systems.named_symbolic_system import PortMap
from maskless.systems.plant.pneumatic_physics import (
    GAUGE_PRESSURE,
    LIFT,
    LIFT_RATE,
    gauge_pressure_rate,
    net_flow_of_state,
)
from maskless.systems.plant.pneumatic_plant import (
    equilibrium_state,
    load_pneumatic_parameters,
    make_pneumatic_plant,
)

PERIOD_S = 0.1
START_S, DURATION_S = 1.0, 2.0


FRAME_RATES_HZ = {"kinect_v1": 1 / PERIOD_S, "kinect_v2": 1 / PERIOD_S}


def fault(kind, **fields) -> FaultConfig:
    target = "kinect_v1" if kind in CAMERA_FAULTS else ""
    return FaultConfig(kind=kind, target=target, start_s=START_S, duration_s=DURATION_S, **fields)


def run_camera(faults, frames=50, valid=1.0, seed=0, camera_log=None):
    """The fault system alone on a camera whose distance ramps 1 mm per frame from 0.8 m.

    Returns the frame times and the (distance, valid) the filter would read at each. With
    ``camera_log`` (a list), the camera's frames change at its frame ticks, as a real camera's
    do (a ZeroOrderHold), and the distance it delivered at each is appended to the list.
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
    logs = {}
    if camera_log is not None:
        frames_held = builder.AddSystem(ZeroOrderHold(PERIOD_S, 1))
        builder.Connect(camera.outputs["distance_m"], frames_held.get_input_port())
        camera.outputs["distance_m"] = frames_held.get_output_port()
        logs["camera"] = builder.AddSystem(VectorLogSink(1, PERIOD_S))
        builder.Connect(frames_held.get_output_port(), logs["camera"].get_input_port())
    ports = add_camera_faults(builder, "kinect_v1", faults, camera, PERIOD_S)
    for port in ("distance_m", "valid"):
        logs[port] = builder.AddSystem(VectorLogSink(1, PERIOD_S))
        builder.Connect(ports.outputs[port], logs[port].get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    simulator.AdvanceTo((frames - 0.5) * PERIOD_S)
    context = simulator.get_context()
    log = logs["distance_m"].FindLog(context)
    if camera_log is not None:
        camera_log.extend(logs["camera"].FindLog(context).data()[0])
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
        validate_faults({"f": broken}, FRAME_RATES_HZ)


def test_a_fault_that_starts_after_the_run_changes_nothing(tmp_path):
    """Not a draw of any other source moves: the dropouts' RandomSource is added last."""
    plain = simulate(load_scenario(duration_s=12.0))
    late = {
        "late": FaultConfig("camera_dropouts", "kinect_v2", 50.0, 10.0, probability=0.5),
        "later": FaultConfig("camera_bias", "kinect_v1", 50.0, 10.0, bias_m=0.01),
        "spike": FaultConfig("latency_spike", "kinect_v1", 50.0, 10.0, latency_s=0.5),
        "ticks": FaultConfig("missed_tick", "", 50.0, 10.0, probability=0.5),
    }
    faulted = simulate(load_scenario(duration_s=12.0, faults=late))
    for name, signal in plain.signals.items():
        np.testing.assert_array_equal(faulted.signals[name].values, signal.values, err_msg=name)


def test_a_plant_fault_that_starts_after_the_run_changes_nothing_but_rounding():
    plain = simulate(load_scenario(duration_s=12.0))
    late = {
        "supply": FaultConfig("supply_loss", "", 50.0, 10.0, supply_fraction=0.5),
        "leak": FaultConfig("leak_increase", "", 50.0, 10.0, leak_factor=2.0),
    }
    faulted = simulate(load_scenario(duration_s=12.0, faults=late))
    for name, signal in plain.signals.items():
        # Rounding: 1e-15 m on a height, 1e-13 of the value on a pressure of ~1600 Pa.
        np.testing.assert_allclose(
            faulted.signals[name].values, signal.values, rtol=1e-13, atol=1e-15, err_msg=name
        )


def test_both_cameras_dead_leave_the_loop_blind_and_stuck_valves_move_the_head():
    """What the faults do to the plant and the estimate, whatever the supervisor makes of it."""
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
        "supply": FaultConfig("supply_loss", "", 0.0, 100.0, supply_fraction=0.5),
        "leak": FaultConfig("leak_increase", "", 0.0, 100.0, leak_factor=3.0),
        "spike": FaultConfig("latency_spike", "kinect_v1", 0.0, 100.0, latency_s=0.5),
        "ticks": FaultConfig("missed_tick", "", 0.0, 100.0, probability=0.5),
    }
    faulted = build_closed_loop(load_scenario(faults=faults), record=False)
    for name in ("K", "M", "augmented_A", "augmented_B", "state_per_reference"):
        np.testing.assert_array_equal(getattr(faulted.design, name), getattr(plain.design, name))
    assert camera_faults_of(faults, "kinect_v1") == [faults["bias"], faults["spike"]]


@pytest.mark.parametrize(
    "example", sorted(p.name for p in asset_path("simulation.yaml").parent.glob("faults/*.yaml"))
)
def test_each_shipped_fault_example_loads_and_its_faults_start_at_30_s(example):
    scenario = load_scenario(asset_path(f"faults/{example}"))
    assert scenario.faults and all(f.start_s == 30.0 for f in scenario.faults.values())


@pytest.mark.parametrize("latency_s, frames", [(0.3, 3), (0.12, 1), (0.26, 3)])
def test_a_latency_spike_delivers_the_frame_from_latency_s_ago_in_its_window_only(
    latency_s, frames
):
    """Rounded to whole frames: 0.26 s of 0.1 s frames is 3 frames."""
    delivered = []
    times, distance, valid = run_camera(
        [fault("latency_spike", latency_s=latency_s)], camera_log=delivered
    )
    delivered = np.array(delivered)
    inside = in_window(times)
    late = np.flatnonzero(inside)
    assert late[0] >= frames  # the delay line was full when the window opened
    np.testing.assert_array_equal(distance[late], delivered[late - frames])
    np.testing.assert_array_equal(distance[~inside], delivered[~inside])
    assert np.all(valid == 1)
    # The frames changed from one tick to the next, so the delay is seen, not assumed.
    assert np.all(np.abs(distance[late] - delivered[late]) > frames * 0.9e-3)


def test_a_latency_spike_before_the_line_fills_delivers_no_frame():
    early = FaultConfig("latency_spike", "kinect_v1", 0.0, 1.0, latency_s=0.5)
    times, _, valid = run_camera([early], frames=20, camera_log=[])
    assert np.all(valid[times < 0.5 - 1e-9] == 0)  # nothing 0.5 s old exists yet
    assert np.all(valid[times >= 0.5 - 1e-9] == 1)


def test_a_latency_spike_acts_before_a_bias_whatever_their_order():
    spike, bias = fault("latency_spike", latency_s=0.2), fault("camera_bias", bias_m=0.02)
    first = run_camera([spike, bias], camera_log=[])[1]
    np.testing.assert_array_equal(first, run_camera([bias, spike], camera_log=[])[1])


def run_ticks(faults, seed=0, ticks=40):
    """The missed-tick system alone on commands that ramp 1 mA per tick (inlet) and fall 2 mA.

    Returns the tick times, the commands and the currents delivered (rows inlet, outlet).
    """
    builder = DiagramBuilder()
    end_s = ticks * PERIOD_S
    ramp = PiecewisePolynomial.FirstOrderHold(
        [0.0, end_s], np.array([[0.1, 0.1 + ticks * 1e-3], [0.3, 0.3 - ticks * 2e-3]])
    )
    # A controller's commands change at its ticks.
    commands = builder.AddSystem(ZeroOrderHold(PERIOD_S, 2))
    builder.Connect(
        builder.AddSystem(TrajectorySource(ramp)).get_output_port(), commands.get_input_port()
    )
    split = builder.AddSystem(Demultiplexer(2))
    builder.Connect(commands.get_output_port(), split.get_input_port())
    inlet, outlet = add_controller_faults(
        builder, faults, split.get_output_port(0), split.get_output_port(1), PERIOD_S
    )
    logs = []
    for port in (commands.get_output_port(), inlet, outlet):
        logs.append(builder.AddSystem(VectorLogSink(port.size(), PERIOD_S)))
        builder.Connect(port, logs[-1].get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed))
    simulator.AdvanceTo((ticks - 0.5) * PERIOD_S)
    found = [log.FindLog(simulator.get_context()) for log in logs]
    delivered = np.vstack([found[1].data(), found[2].data()])
    return found[0].sample_times(), found[0].data(), delivered


def test_ticks_missed_with_certainty_hold_the_commands_exactly_in_their_window_only():
    times, commands, delivered = run_ticks({"f": fault("missed_tick", probability=1.0)})
    # A log sample at a tick reads the value held over the tick before it (Drake publishes
    # before it updates), so the value from tick k on is sample k + 1.
    ticks, commands, delivered = times[:-1], commands[:, 1:], delivered[:, 1:]
    inside = in_window(ticks)
    before = np.flatnonzero(inside)[0] - 1
    held = commands[:, [before]] * np.ones((1, inside.sum()))
    np.testing.assert_array_equal(delivered[:, inside], held)
    np.testing.assert_array_equal(delivered[:, ~inside], commands[:, ~inside])
    assert np.unique(commands[0, inside]).size == inside.sum()  # the commands did change


def test_ticks_never_missed_pass_the_commands_and_no_fault_adds_nothing():
    times, commands, delivered = run_ticks({"f": fault("missed_tick", probability=0.0)})
    np.testing.assert_array_equal(delivered, commands)
    builder = DiagramBuilder()
    source = builder.AddSystem(ConstantVectorSource([0.1])).get_output_port()
    stuck = {"s": fault("inlet_stuck", current_a=0.0)}
    assert add_controller_faults(builder, stuck, source, source, PERIOD_S) == (source, source)


def test_missed_ticks_are_drawn_at_their_probability_and_seeded():
    overrun = {"f": FaultConfig("missed_tick", "", 0.0, 1e6, probability=0.3)}
    _, commands, delivered = run_ticks(overrun, ticks=3000)
    # A missed tick delivers the tick before's current, never this tick's command.
    missed = delivered[0] != commands[0]
    assert stats.binomtest(int(missed.sum()), missed.size, 0.3).pvalue > 0.01
    # Each delivered current is a command of this tick or of an earlier one, on both valves.
    assert np.all(np.isin(delivered[0], commands[0])) and np.all(np.isin(delivered[1], commands[1]))
    assert np.array_equal((delivered[1] != commands[1]), missed)  # both valves miss together
    same = [run_ticks(overrun, seed=4)[2] for _ in range(2)]
    np.testing.assert_array_equal(same[0], same[1])
    assert not np.array_equal(same[0], run_ticks(overrun, seed=5)[2])


@pytest.fixture(scope="module")
def pneumatic():
    return load_pneumatic_parameters()


def plant_update(p, faults, time_s, state, currents, context_parameters=()):
    """The compiled plant's next state from ``state`` at ``time_s``, built with ``faults``."""
    origin = equilibrium_state(p, 0.0, 0.0)
    diagram = make_pneumatic_plant(
        p,
        origin,
        p.simulation_step_s,
        context_parameters=context_parameters,
        time_factors=plant_fault_factors(faults),
    )
    context = diagram.CreateDefaultContext()
    context.SetTime(time_s)
    for name, current in zip(
        ("inlet_valve_current_a", "outlet_valve_current_a"), currents, strict=True
    ):
        diagram.GetInputPort(name).FixValue(context, [current])
    plant = diagram.GetSubsystemByName("pneumatic_plant")
    plant_context = diagram.GetMutableSubsystemContext(plant, context)
    plant_context.SetDiscreteState(state - origin)
    return plant.EvalUniquePeriodicDiscreteUpdate(plant_context).value() + origin


@pytest.mark.parametrize(
    "kind, field_name, value, constant",
    [
        ("supply_loss", "supply_fraction", 0.4, "supply_gauge_pressure_pa"),
        ("supply_loss", "supply_fraction", 0.0, "supply_gauge_pressure_pa"),
        ("leak_increase", "leak_factor", 8.0, "leak_sonic_conductance_m3_s_pa"),
    ],
)
@pytest.mark.parametrize(
    "context_parameters", [(), ("supply_gauge_pressure_pa", "leak_sonic_conductance_m3_s_pa")]
)
def test_a_plant_fault_changes_the_pressure_rate_as_the_physics_does_in_its_window_only(
    pneumatic, kind, field_name, value, constant, context_parameters
):
    """The pressure step against pneumatic_physics' rate with the changed constant, or not."""
    p = pneumatic
    faults = {"f": fault(kind, **{field_name: value})}
    state = equilibrium_state(p, 0.12, 0.0)  # inlet open: the supply matters; at rest nominally
    state[GAUGE_PRESSURE] += 500.0  # off rest, so the leak's flow is not balanced either
    changed = dataclasses.replace(p, **{constant: value * getattr(p, constant)})
    rates = {}
    for time_s in (0.5, START_S, 2.0, START_S + DURATION_S, 4.0):
        step = plant_update(p, faults, time_s, state, (0.12, 0.0), context_parameters)
        acting = changed if START_S <= time_s < START_S + DURATION_S else p
        expected = gauge_pressure_rate(
            state[GAUGE_PRESSURE],
            step[LIFT],
            step[LIFT_RATE],
            net_flow_of_state(state, acting),
            acting,
        )
        rate = (step[GAUGE_PRESSURE] - state[GAUGE_PRESSURE]) / p.simulation_step_s
        assert rate == pytest.approx(expected, rel=1e-9, abs=1e-6), time_s
        rates[time_s] = rate
    assert abs(rates[2.0] - rates[0.5]) > 100.0  # Pa/s: the fault did change the flow
    assert rates[4.0] == rates[0.5]


def test_only_plant_faults_make_plant_factors():
    assert plant_fault_factors({"f": fault("missed_tick", probability=0.5)}) is None
    both = {
        "a": fault("supply_loss", supply_fraction=0.5),
        "b": FaultConfig("supply_loss", "", 2.0, 2.0, supply_fraction=0.5),
    }
    time = Variable("t")
    factors = plant_fault_factors(both)(time)
    assert set(factors) == {"supply_gauge_pressure_pa"}
    factor = factors["supply_gauge_pressure_pa"]
    # Overlapping windows multiply: 1 before, 0.5 in one, 0.25 in both.
    assert [factor.Evaluate({time: t}) for t in (0.5, 1.5, 2.5, 3.5)] == [1.0, 0.5, 0.25, 0.5]


@pytest.mark.parametrize(
    "fields, message",
    [
        (
            dict(kind="supply_loss", supply_fraction=1.0),
            r"faults.f.supply_fraction = 1.0: expected a fraction in \[0, 1\)",
        ),
        (dict(kind="supply_loss", supply_fraction=-0.1), "faults.f.supply_fraction = -0.1"),
        (
            dict(kind="supply_loss", supply_fraction=0.5, latency_s=0.2),
            "faults.f.latency_s = 0.2: expected 0: supply_loss does not use it",
        ),
        (
            dict(kind="leak_increase", leak_factor=1.0),
            "faults.f.leak_factor = 1.0: expected a finite factor > 1",
        ),
        (dict(kind="leak_increase", leak_factor=float("inf")), "faults.f.leak_factor = inf"),
        (
            dict(kind="leak_increase", leak_factor=2.0, supply_fraction=0.5),
            "faults.f.supply_fraction = 0.5: expected 0: leak_increase does not use it",
        ),
        (
            dict(kind="latency_spike", target="kinect_v1", latency_s=1.5),
            r"faults.f.latency_s = 1.5: expected 0 to 1 s \(a spike of 1 s is ten times",
        ),
        (
            dict(kind="latency_spike", target="kinect_v1", latency_s=0.04),
            "faults.f.latency_s = 0.04: expected at least half a frame of kinect_v1, 0.0500 s",
        ),
        (dict(kind="latency_spike", latency_s=0.2), "faults.f.target = : expected a camera"),
        (
            dict(kind="latency_spike", target="kinect_v1", latency_s=0.2, probability=0.5),
            "faults.f.probability = 0.5: expected 0: latency_spike does not use it",
        ),
        (
            dict(kind="missed_tick", probability=0.0),
            r"faults.f.probability = 0.0: expected a probability in \(0, 1\]",
        ),
        (dict(kind="missed_tick", probability=1.5), "faults.f.probability = 1.5"),
        (
            dict(kind="missed_tick", target="kinect_v1", probability=0.5),
            "faults.f.target = kinect_v1: expected nothing",
        ),
        (
            dict(kind="missed_tick", probability=0.5, current_a=0.1),
            "faults.f.current_a = 0.1: expected 0: missed_tick does not use it",
        ),
    ],
)
def test_a_malformed_new_fault_is_refused_naming_its_field(fields, message):
    broken = FaultConfig(start_s=START_S, duration_s=DURATION_S, **fields)
    with pytest.raises(ConfigError, match=message):
        validate_faults({"f": broken}, FRAME_RATES_HZ)


@pytest.mark.parametrize(
    "kind, field_name, value",
    [("supply_loss", "supply_fraction", 0.5), ("leak_increase", "leak_factor", 2.0)],
)
def test_a_plant_fault_on_a_linear_plant_is_refused_saying_why(kind, field_name, value):
    faults = {"f": fault(kind, **{field_name: value})}
    with pytest.raises(ConfigError, match=f"faults.f.kind = {kind}: expected a fault the paper"):
        load_scenario(plant=PaperPlant(), faults=faults)
    assert load_scenario(faults=faults).faults  # the pneumatic plant has it


NEW_FAULTS = {
    "supply_loss": FaultConfig("supply_loss", "", 2.0, 4.0, supply_fraction=0.0),
    "leak_increase": FaultConfig("leak_increase", "", 2.0, 4.0, leak_factor=4.0),
    "latency_spike": FaultConfig("latency_spike", "kinect_v1", 2.0, 4.0, latency_s=1.0),
    "missed_tick": FaultConfig("missed_tick", "", 2.0, 4.0, probability=0.7),
}


@pytest.mark.parametrize("kind", sorted(NEW_FAULTS))
def test_a_loop_with_each_new_fault_runs_with_valve_currents_in_range(kind):
    scenario = load_scenario(duration_s=10.0, faults={"f": NEW_FAULTS[kind]})
    run = simulate(scenario)
    for valve in ("inlet", "outlet"):
        current = run.signals[f"{valve}_valve_current_a"].values[0]
        saturation = getattr(scenario.pneumatic, valve).saturation_current_a
        assert np.all(np.isfinite(current)) and np.all((current >= 0) & (current <= saturation))
    plain = simulate(load_scenario(duration_s=10.0))
    moved = run.signals["head_height_m"].values[0] - plain.signals["head_height_m"].values[0]
    before = run.signals["head_height_m"].times_s < 2.0
    # Nothing happens before the window; a plant fault's factors are evaluated, not folded into
    # the plant's numbers, which may round differently (by 1e-17 m, measured).
    assert np.all(np.abs(moved[before]) < 1e-15)
    assert np.any(moved[~before] != 0)  # and something does in it


def test_a_loop_with_missed_ticks_is_seeded():
    ticks = {"f": FaultConfig("missed_tick", "", 1.0, 10.0, probability=0.5)}
    runs = [
        simulate(load_scenario(duration_s=8.0, random_seed=seed, faults=ticks))
        for seed in (3, 3, 4)
    ]
    for name, signal in runs[0].signals.items():
        np.testing.assert_array_equal(runs[1].signals[name].values, signal.values, err_msg=name)
    inlet = [run.signals["inlet_valve_current_a"].values for run in runs]
    assert not np.array_equal(inlet[0], inlet[2])
