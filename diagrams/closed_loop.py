"""The paper's closed loop as one named Drake Diagram.

reference -> LQG controller -> valve limits -> paper plant -> head height -> kinect_v1, kinect_v2
-> local Kalman filters -> track-to-track fusion -> fused height -> LQG controller.
"""

from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Multiplexer, Saturation, TrajectorySource, VectorLogSink
from pydrake.trajectories import PiecewisePolynomial

from maskless.diagrams.config import ReferenceConfig, SimulationConfig
from maskless.systems.depth_sensor import add_depth_sensor
from maskless.systems.local_kalman_filter import add_local_kalman_filter
from maskless.systems.lqg_controller import LqgDesign, add_lqg_controller, design_lqg
from maskless.systems.paper_parameters import (
    IdentifiedModel,
    paper_filter_variances_si,
    paper_identified_model,
    paper_lqg_weights,
)
from maskless.systems.paper_plant import add_paper_plant, operating_head_height_m
from maskless.systems.track_fusion import add_track_fusion
from maskless.systems.units import ma_to_a

# Far beyond any run, so the last reference value holds for the rest of the simulation.
_REFERENCE_HOLD_S = 1.0e9


@dataclass
class ClosedLoop:
    """A built closed loop and what a caller needs to read it.

    Attributes:
        diagram: the Diagram, named "paper_closed_loop".
        loggers: exported output name -> (VectorLogSink, the rows of its log that hold that
            output); empty when built without recording.
        model: the plant model the controller was designed on.
        design: the controller's gains.
        start_height_m: head height above the table at t = 0 (m).
        sensor_names: the cameras, in order.
    """

    diagram: Diagram
    model: IdentifiedModel
    design: LqgDesign
    start_height_m: float
    sensor_names: list[str]
    loggers: dict[str, tuple[VectorLogSink, slice]] = field(default_factory=dict)


def make_reference_trajectory(reference: ReferenceConfig, start_height_m: float):
    """The reference as a zero-order-hold trajectory of absolute heights (m)."""
    times = [0.0, *reference.step_times_s, _REFERENCE_HOLD_S]
    heights = [start_height_m] + [start_height_m + o for o in reference.step_offsets_m]
    heights.append(heights[-1])
    return PiecewisePolynomial.ZeroOrderHold(times, np.array(heights).reshape(1, -1))


def _add_loggers(builder: DiagramBuilder, logged: dict) -> dict[str, tuple[VectorLogSink, slice]]:
    """One VectorLogSink per logging period, fed by a Multiplexer of that period's signals: each
    sink is a publish event every period, so fewer sinks make a cheaper step."""
    by_period: dict[float, list[str]] = {}
    for signal, (_, period_s) in logged.items():
        by_period.setdefault(period_s, []).append(signal)
    loggers = {}
    for index, (period_s, signals) in enumerate(by_period.items()):
        sizes = [logged[signal][0].size() for signal in signals]
        mux = builder.AddNamedSystem(f"log_{index}.signals", Multiplexer(sizes))
        sink = builder.AddNamedSystem(f"log_{index}", VectorLogSink(sum(sizes), period_s))
        builder.Connect(mux.get_output_port(), sink.get_input_port())
        row = 0
        for port_index, (signal, size) in enumerate(zip(signals, sizes, strict=True)):
            builder.Connect(logged[signal][0], mux.get_input_port(port_index))
            loggers[signal] = (sink, slice(row, row + size))
            row += size
    return loggers


def build_paper_closed_loop(config: SimulationConfig, record: bool = True) -> ClosedLoop:
    """Wires the paper's whole chain for ``config``.

    Args:
        config: a validated SimulationConfig.
        record: add VectorLogSinks for every recorded signal (the core-speed benchmark omits them).

    Exported outputs: ``reference_head_height_m``, ``head_height_m``, ``valve_current_a``,
    ``fusion.estimated_state``, ``fusion.covariance``, and for each camera ``{name}.distance_m``,
    ``{name}.valid``, ``{name}_filter.estimated_state`` and ``{name}_filter.covariance``.
    """
    paper = config.paper
    model = paper_identified_model(paper)
    design = design_lqg(model, paper_lqg_weights(paper))
    # The model was identified on the fused distance in the Kinect v2 frame (Sec. III-B).
    model_camera_height_m = config.kinect_v2.mount_height_m
    start_height_m = operating_head_height_m(model, model_camera_height_m)
    variances = paper_filter_variances_si(paper)
    saturation_current_a = ma_to_a(paper.valve_saturation_current_ma)

    builder = DiagramBuilder()
    # Components are added flat (add_*), not as nested Diagrams: nesting nearly doubles the cost of
    # a step (benchmarks/system_overhead.py), and the loop must run >= 1000x faster than real time.
    reference = builder.AddNamedSystem(
        "reference",
        TrajectorySource(make_reference_trajectory(config.reference, start_height_m)),
    )
    valve_currents_a = (ma_to_a(paper.valve_starting_current_ma), saturation_current_a)
    controller = add_lqg_controller(
        builder, model, design, model_camera_height_m, valve_currents_a, "paper_lqg"
    )
    limits = builder.AddNamedSystem(
        "valve_current_limits", Saturation([0.0], [saturation_current_a])
    )
    plant = add_paper_plant(
        builder, model, model_camera_height_m, *valve_currents_a, name="paper_plant"
    )
    sensor_names = list(config.sensors())
    filters = {}
    sensors = {}
    for name, sensor_config in config.sensors().items():
        sensor = add_depth_sensor(builder, name, sensor_config)
        local_filter = add_local_kalman_filter(
            builder,
            f"{name}_filter",
            camera_height_m=sensor_config.mount_height_m,
            frame_period_s=1.0 / sensor_config.frame_rate_hz,
            acceleration_variance_m2_s4=variances["acceleration_variance_m2_s4"],
            measurement_variance_m2=variances[name],
            initial_height_m=start_height_m,
            valid_range_m=(sensor_config.min_range_m, sensor_config.max_range_m),
            config=config.local_filter,
        )
        builder.Connect(plant.outputs["head_height_m"], sensor.inputs["head_height_m"])
        for port in ("distance_m", "valid"):
            builder.Connect(sensor.outputs[port], local_filter.inputs[port])
        sensors[name], filters[name] = sensor, local_filter
    fusion = add_track_fusion(builder, sensor_names, name="fusion")
    for name, local_filter in filters.items():
        for port in ("estimated_state", "covariance"):
            builder.Connect(local_filter.outputs[port], fusion.inputs[f"{name}_{port}"])
    builder.Connect(fusion.outputs["estimated_state"], controller.inputs["fused_estimated_state"])
    builder.Connect(reference.get_output_port(), controller.inputs["reference_head_height_m"])
    builder.Connect(controller.outputs["valve_current_a"], limits.get_input_port())
    builder.Connect(limits.get_output_port(), plant.inputs["valve_current_a"])
    builder.Connect(limits.get_output_port(), controller.inputs["applied_current_a"])

    exported = {
        "reference_head_height_m": reference.get_output_port(),
        "head_height_m": plant.outputs["head_height_m"],
        "valve_current_a": limits.get_output_port(),
        "fusion.estimated_state": fusion.outputs["estimated_state"],
        "fusion.covariance": fusion.outputs["covariance"],
    }
    for name in sensor_names:
        for port in ("distance_m", "valid"):
            exported[f"{name}.{port}"] = sensors[name].outputs[port]
        for port in ("estimated_state", "covariance"):
            exported[f"{name}_filter.{port}"] = filters[name].outputs[port]
    for port_name, port in exported.items():
        builder.ExportOutput(port, port_name)

    loggers = {}
    if record:
        # Every exported output is logged: camera frames at their frame period, the rest at the
        # controller's, so estimates and command share timestamps.
        frame_periods_s = {
            f"{name}.{port}": 1.0 / config.sensors()[name].frame_rate_hz
            for name in sensor_names
            for port in ("distance_m", "valid")
        }
        logged = {
            signal: (port, frame_periods_s.get(signal, model.sample_period_s))
            for signal, port in exported.items()
        }
        loggers = _add_loggers(builder, logged)

    diagram = builder.Build()
    diagram.set_name("paper_closed_loop")
    return ClosedLoop(
        diagram=diagram,
        model=model,
        design=design,
        start_height_m=start_height_m,
        sensor_names=sensor_names,
        loggers=loggers,
    )
