"""The closed loop as one named Drake Diagram.

reference -> controller -> inlet and outlet valve currents -> plant -> head height -> each camera
-> its local Kalman filter -> track-to-track fusion -> fused height -> controller.

The plant is the pneumatic "real robot", the paper's identified model or a model file; the
controller is the offset-free LQG or the paper's LQG (which drives the inlet only).

A sweep over pneumatic plants (a Monte Carlo over patients' heads) builds one loop and writes each
draw's constants into its Context (``set_plant_parameters``) instead of building a loop per draw.
"""

import functools
from collections.abc import Collection
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.systems.framework import Context, Diagram, DiagramBuilder, InputPort, OutputPort
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Multiplexer,
    Saturation,
    VectorLogSink,
)

from maskless.camera_images import CameraFrame
from maskless.diagrams.controller_design import NominalPneumatic, offset_free_design
from maskless.diagrams.scenario import (
    PaperLqg,
    PneumaticPlant,
    ReferenceConfig,
    Scenario,
    kind_name,
)
from maskless.diagrams.scenario_plant import linear_plant_model, paper_valve_currents_a
from maskless.errors import ConfigError
from maskless.systems.control.offset_free_lqg import add_offset_free_lqg
from maskless.systems.control.paper_lqg import add_paper_lqg, paper_lqg
from maskless.systems.control.safety_supervisor import SAFETY_STATUS, add_safety_supervisor
from maskless.systems.control.step_reference import add_step_reference
from maskless.systems.fault_injection import (
    add_camera_faults,
    add_controller_faults,
    add_valve_faults,
    camera_faults_of,
    plant_fault_factors,
)
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.late_random_sources import LateRandomSources
from maskless.systems.linear_model import LinearModel
from maskless.systems.named_symbolic_system import PortMap
from maskless.systems.paper_parameters import paper_filter_variances_si
from maskless.systems.plant.hammerstein_plant import add_hammerstein_plant
from maskless.systems.plant.linear_model_plant import (
    add_linear_model_plant,
    operating_head_height_m,
)
from maskless.systems.plant.patient_motion import add_patient_motion
from maskless.systems.plant.pneumatic_physics import LIFT, PneumaticParameters
from maskless.systems.plant.pneumatic_plant import (
    add_pneumatic_plant,
    equilibrium_state,
    set_pneumatic_parameters,
)
from maskless.systems.plumbing import remove_plumbing
from maskless.systems.sensing.camera_error import add_camera_error
from maskless.systems.sensing.depth_sensor import add_depth_sensor, add_depth_sensors
from maskless.systems.sensing.local_kalman_filter import local_kalman_filter_system
from maskless.systems.sensing.pressure_sensor import add_pressure_sensor
from maskless.systems.sensing.track_fusion import add_track_fusion
from maskless.systems.symbolic_banks import add_symbolic_banks

PNEUMATIC_PLANT_NAME = "pneumatic_plant"
# The closed loop's head-height reference (``step_reference``), whose levels a Context can change.
REFERENCE_NAME = "reference"


@dataclass
class Signal:
    """A logged signal: sample times (s) and values (rows = the port's components)."""

    times_s: np.ndarray
    values: np.ndarray


@dataclass
class ClosedLoop:
    """A built closed loop and what a caller needs to read it.

    Attributes:
        diagram: the Diagram, named "{plant}_{controller}_closed_loop".
        plant: which plant ("pneumatic", "paper" or "identified").
        controller: which controller ("offset-free-lqg" or "paper-lqg").
        model: the linear model the controller was designed on (its output the camera
            distance for paper-lqg, the head height for offset-free-lqg); None when nothing
            closes the loop (an excitation run).
        design: the controller's gains (LqgDesign or OffsetFreeLqgDesign).
        start_height_m: head height above the table at t = 0 (m).
        sensor_names: the cameras, in order.
        loggers: exported output name -> (VectorLogSink, the rows of its log that hold that
            output); empty when built without recording.
        frames: the rendered cameras' recorded frames, appended while the loop runs (a
            publish event's side effect); empty without rendered cameras or recording.
    """

    diagram: Diagram
    plant: str
    controller: str
    model: LinearModel | None
    design: object
    start_height_m: float
    sensor_names: list[str]
    loggers: dict[str, tuple[VectorLogSink, slice]] = field(default_factory=dict)
    frames: list[CameraFrame] = field(default_factory=list)


@dataclass
class AddedPlant:
    """An added plant's ports and where its head starts (m above the table)."""

    inlet: InputPort
    outlet: InputPort
    head_height: OutputPort
    start_height_m: float
    gauge_pressure: OutputPort | None = None


# The ConstantVectorSource a person's reset of the safety supervisor comes from.
SAFETY_RESET_NAME = "safety_reset"


def reference_levels(reference: ReferenceConfig, start_height_m: float) -> list[float]:
    """The reference's absolute heights (m): the start, then the height after each step."""
    return [start_height_m] + [start_height_m + o for o in reference.step_offsets_m]


def _add_loggers(builder: DiagramBuilder, logged: dict) -> dict[str, tuple[VectorLogSink, slice]]:
    """One VectorLogSink per logging period, fed by a Multiplexer of that period's signals.

    Each sink is a publish event every period, so fewer sinks make a cheaper step.
    """
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


def add_plant(
    builder: DiagramBuilder,
    config: Scenario,
    nominal: "NominalPneumatic | None",
    plant_context_parameters: Collection[str] = (),
) -> AddedPlant:
    """Adds ``config.plant``, at rest where it starts.

    The pneumatic plant rests at ``config.start_lift_m`` (its starting currents come from
    ``nominal``'s allocation); a model rests at its operating point.
    ``plant_context_parameters``: the pneumatic plant's ``context_parameters``.
    """
    if isinstance(config.plant, PneumaticPlant):
        p = config.pneumatic
        start_inlet_a, start_outlet_a = nominal.allocation.currents(config.start_lift_m)
        state = equilibrium_state(p, float(start_inlet_a), float(start_outlet_a))
        plant = add_pneumatic_plant(
            builder,
            p,
            state,
            p.simulation_step_s,
            name=PNEUMATIC_PLANT_NAME,
            context_parameters=plant_context_parameters,
            time_factors=plant_fault_factors(config.faults),
        )
        # The supervisor reads the bladder's gauge pressure through the pressure sensor
        # (assemble_loop), the recording as it is.
        return AddedPlant(
            inlet=plant.inputs["inlet_valve_current_a"],
            outlet=plant.inputs["outlet_valve_current_a"],
            head_height=plant.outputs["head_height_m"],
            start_height_m=p.rest_head_height_m + state[LIFT],
            gauge_pressure=plant.outputs["bladder_gauge_pressure_pa"],
        )
    model, camera_height_m = linear_plant_model(config)
    if isinstance(model, HammersteinModel):
        plant = add_hammerstein_plant(builder, model, name=f"{kind_name(config.plant)}_plant")
        return AddedPlant(
            inlet=plant.inputs["inlet_valve_current_a"],
            outlet=plant.inputs["outlet_valve_current_a"],
            head_height=plant.outputs["head_height_m"],
            start_height_m=model.operating_output,
        )
    plant = add_linear_model_plant(
        builder,
        model,
        camera_height_m,
        *paper_valve_currents_a(config.paper),
        name=f"{kind_name(config.plant)}_plant",
    )
    return AddedPlant(
        inlet=plant.inputs["inlet_valve_current_a"],
        outlet=plant.inputs["outlet_valve_current_a"],
        head_height=plant.outputs["head_height_m"],
        start_height_m=operating_head_height_m(model, camera_height_m),
    )


@dataclass
class SensingChain:
    """The added cameras, their local filters and the fusion site (PortMaps by camera name)."""

    sensor_names: list[str]
    sensors: dict
    filters: dict
    fusion: object


def add_cameras(
    builder: DiagramBuilder,
    config: Scenario,
    head_height: OutputPort,
    frames: list[CameraFrame] | None,
    late: LateRandomSources,
) -> dict[str, PortMap]:
    """Adds every camera watching ``head_height``: a measurement model, or a rendered camera.

    A camera whose ``rendering.enabled`` is set renders the scene (added once, for all of them)
    and finds the face in its images; either way its ``error`` section, when enabled, is added to
    what it measures; with ``frames``, each rendered camera appends a frame to it
    at least ``config.camera_image_rate_hz`` times a second (every whole number of frames that
    gives it: every 7th of 15 frames a second for 2 Hz). The RandomSources of the cameras'
    errors and faults wait in ``late``, so the cameras' own sources keep their seeding order.
    """
    sensors = {}
    scene = None
    # Camera models alone are added as banks (a step costs less); beside a rendered camera, each
    # is added in its turn, so every camera's RandomSource keeps its place in the seeding order.
    rendered = any(camera.rendering.enabled for camera in config.cameras.values())
    models = {} if rendered else add_depth_sensors(builder, config.cameras)
    for name, camera in config.cameras.items():
        if camera.rendering.enabled:
            if scene is None:
                # Imported here: OpenCV and scipy.stats would add ~0.3 s to every run's start.
                from maskless.systems.sensing.camera_scene import add_camera_scene

                scene = add_camera_scene(builder, head_height)
            sensor = _add_rendered_camera(builder, config, name, scene, frames)
        else:
            sensor = models[name] if name in models else add_depth_sensor(builder, name, camera)
            builder.Connect(head_height, sensor.inputs["head_height_m"])
        frame_period_s = 1.0 / camera.frame_rate_hz
        measured = add_camera_error(builder, name, camera.error, sensor, frame_period_s, late)
        sensors[name] = add_camera_faults(
            builder, name, camera_faults_of(config.faults, name), measured, frame_period_s, late
        )
    return sensors


def _add_rendered_camera(builder, config: Scenario, name: str, scene, frames) -> PortMap:
    """A rendered camera of ``scene``, recording into ``frames`` (when given)."""
    from maskless.systems.sensing.rendered_depth_sensor import add_rendered_depth_sensor

    camera = config.cameras[name]
    return add_rendered_depth_sensor(
        builder,
        name,
        camera,
        scene,
        frame_sink=None if frames is None else functools.partial(_append_frame, frames),
        record_every_frames=max(1, int(camera.frame_rate_hz // config.camera_image_rate_hz)),
    )


def _append_frame(frames: list, camera: str, time_s: float, rgb, measurement) -> None:
    frames.append(
        CameraFrame(
            camera=camera,
            time_s=time_s,
            rgb=rgb,
            face_box=measurement.face_box,
            eye_boxes=measurement.eye_boxes,
            region_box=measurement.region_box,
            distance_m=measurement.distance_m,
            valid=measurement.valid,
        )
    )


def add_sensing_chain(
    builder: DiagramBuilder,
    config: Scenario,
    head_height: OutputPort,
    start_height_m,
    frames: list[CameraFrame] | None,
    late: LateRandomSources,
) -> SensingChain:
    """Adds every camera watching ``head_height``, a local Kalman filter on each, and the fusion.

    The filters start at ``start_height_m``; the track-to-track fusion combines their tracks.
    Rendered cameras append recorded frames to ``frames`` (``add_cameras``).
    """
    variances = paper_filter_variances_si(config.paper)
    sensors = add_cameras(builder, config, head_height, frames, late)
    # The filters of one frame rate are one bank (a step costs less than a system each).
    systems = {
        f"{name}_filter": local_kalman_filter_system(
            f"{name}_filter",
            camera_height_m=sensor_config.mount_height_m,
            frame_period_s=1.0 / sensor_config.frame_rate_hz,
            acceleration_variance_m2_s4=variances["acceleration_variance_m2_s4"],
            measurement_variance_m2=variances[sensor_config.model],
            initial_height_m=start_height_m,
            valid_range_m=(sensor_config.min_range_m, sensor_config.max_range_m),
            config=config.local_filter,
            detection=config.fault_detection,
        )
        for name, sensor_config in config.cameras.items()
    }
    added = add_symbolic_banks(builder, systems)
    filters = {}
    for name in config.cameras:
        filters[name] = added[f"{name}_filter"]
        for port in ("distance_m", "valid"):
            builder.Connect(sensors[name].outputs[port], filters[name].inputs[port])
    sensor_names = list(config.cameras)
    fusion = add_track_fusion(builder, sensor_names, config.fault_detection, name="fusion")
    for name, local_filter in filters.items():
        for port in ("estimated_state", "covariance", "health"):
            builder.Connect(local_filter.outputs[port], fusion.inputs[f"{name}_{port}"])
    return SensingChain(sensor_names, sensors, filters, fusion)


def export_and_log(
    builder: DiagramBuilder,
    config: Scenario,
    sensing: SensingChain,
    loop_outputs: dict[str, OutputPort],
    command_period_s: float,
    record: "bool | Collection[str]",
) -> dict[str, tuple[VectorLogSink, slice]]:
    """Exports the loop's outputs and the sensing outputs it logs, and logs each when ``record``.

    ``record`` may also name the outputs to log (a sweep that needs two of them logs no more).

    ``loop_outputs`` (the reference, head height, valve currents and the supervisor's outputs)
    and the fusion's are always exported. Each camera's measurement and each local filter's track
    (``{name}.distance_m``, ``{name}_filter.covariance``, ...) are exported when they are logged:
    the Demultiplexer that names them costs every simulation step its cache work whether they are
    read or not (measured: the four of a two-camera loop, 7-11 µs of a 130-145 µs step;
    ``remove_plumbing`` removes them when nothing reads them). Camera frames are logged at their
    frame period, the rest at ``command_period_s``, so estimates and commands share timestamps.
    """
    exported = dict(loop_outputs)
    for port in ("estimated_state", "covariance", "health"):
        exported[f"fusion.{port}"] = sensing.fusion.outputs[port]
    internal = {}
    for name in sensing.sensor_names:
        for port in ("distance_m", "valid"):
            internal[f"{name}.{port}"] = sensing.sensors[name].outputs[port]
        for port in ("estimated_state", "covariance", "health"):
            internal[f"{name}_filter.{port}"] = sensing.filters[name].outputs[port]
    logged = _logged(config, sensing, exported | internal, command_period_s, record)
    exported |= {signal: port for signal, port in internal.items() if signal in logged}
    for port_name, port in exported.items():
        builder.ExportOutput(port, port_name)
    loggers = _add_loggers(builder, logged)
    remove_plumbing(builder, kept=exported.values())
    return loggers


def _logged(config, sensing, available: dict, command_period_s: float, record) -> dict:
    """The outputs ``record`` asks to log, each with its logging period (none if False)."""
    if not record:
        return {}
    frame_periods_s = {
        f"{name}.{port}": 1.0 / config.cameras[name].frame_rate_hz
        for name in sensing.sensor_names
        for port in ("distance_m", "valid")
    }
    if record is not True:
        unknown = sorted(set(record) - set(available))
        if unknown:
            raise ConfigError(f"no outputs {unknown} to log; the loop has {sorted(available)}")
    return {
        signal: (port, frame_periods_s.get(signal, command_period_s))
        for signal, port in available.items()
        if record is True or signal in record
    }


def build_closed_loop(
    config: Scenario,
    record: "bool | Collection[str]" = True,
    nominal: "NominalPneumatic | None" = None,
    plant_context_parameters: Collection[str] = (),
) -> ClosedLoop:
    """Wires the whole chain for ``config``: its plant, cameras, filters, fusion and controller.

    Args:
        config: a validated Scenario.
        record: add VectorLogSinks for every exported output (the core-speed benchmark omits
            them), or only for the outputs named.
        nominal: ``NominalPneumatic.of(config)`` when the caller has it already (a Monte Carlo
            over head masses shares one); built here otherwise.
        plant_context_parameters: the pneumatic plant's constants that ``set_plant_parameters``
            can change (``pneumatic_plant.add_pneumatic_plant``'s ``context_parameters``). None
            by default (an empty tuple): every constant is compiled into the expressions, bit for
            bit as before and about 3 % faster than ``SWEPT_PARAMETERS``, which a sweep over
            heads builds with (``benchmarks/closed_loop.py``).

    Exported outputs: ``reference_head_height_m``, ``head_height_m``, ``inlet_valve_current_a``,
    ``outlet_valve_current_a``, ``fusion.estimated_state``, ``fusion.covariance``,
    ``fusion.health``, and, when logged (``export_and_log``), for each camera
    ``{name}.distance_m``, ``{name}.valid``, ``{name}_filter.estimated_state``,
    ``{name}_filter.covariance`` and ``{name}_filter.health``; with the safety supervisor
    (``safety.enabled`` and a controller), ``safety.reasons``, ``safety.mode``,
    ``safety.beam_hold``, ``safety.inlet_valve_current_a``, ``safety.outlet_valve_current_a``
    (what the valves get) and ``safety.estimated_head_height_m`` (the controller's estimate it
    judges the beam by); with the pneumatic plant, ``plant.bladder_gauge_pressure_pa``.
    """
    paper = config.paper
    builder = DiagramBuilder()
    # Components are added flat (add_*), not as nested Diagrams: nesting nearly doubles the cost of
    # a step (benchmarks/system_overhead.py), and the loop must run >= 1000x faster than real time.
    if nominal is None and isinstance(config.plant, PneumaticPlant):
        nominal = NominalPneumatic.of(config)
    plant = add_plant(builder, config, nominal, plant_context_parameters)
    start_height_m = plant.start_height_m
    reference = add_step_reference(
        builder,
        config.reference.step_times_s,
        reference_levels(config.reference, start_height_m),
        REFERENCE_NAME,
    ).outputs["reference"]

    if isinstance(config.controller, PaperLqg):
        model, design = paper_lqg(paper)
        valve_currents_a = paper_valve_currents_a(paper)
        saturation_current_a = valve_currents_a[1]
        camera_height_m = config.cameras[config.controller.camera].mount_height_m
        controller = add_paper_lqg(
            builder, model, design, camera_height_m, valve_currents_a, "paper_lqg"
        )
        limits = builder.AddNamedSystem(
            "valve_current_limits", Saturation([0.0], [saturation_current_a])
        )
        builder.Connect(controller.outputs["valve_current_a"], limits.get_input_port())
        builder.Connect(limits.get_output_port(), controller.inputs["applied_current_a"])
        inlet_command = limits.get_output_port()
        # The paper's loop drives the inlet only; the outlet stays shut.
        outlet_command = builder.AddNamedSystem(
            "outlet_valve_shut", ConstantVectorSource([0.0])
        ).get_output_port()
    else:
        design, allocation = offset_free_design(config, nominal)
        model = design.model
        controller = add_offset_free_lqg(
            builder, design, allocation, start_height_m, name="offset_free_lqg"
        )
        inlet_command = controller.outputs["inlet_valve_current_a"]
        outlet_command = controller.outputs["outlet_valve_current_a"]
    controller_name = kind_name(config.controller)
    return assemble_loop(
        builder,
        config,
        plant,
        LoopDrive(
            inlet_command,
            outlet_command,
            reference,
            model.sample_period_s,
            controller_name,
            controller,
        ),
        record,
        f"{kind_name(config.plant)}_{controller_name}_closed_loop".replace("-", "_"),
        model=model,
        design=design,
    )


@dataclass
class LoopDrive:
    """What drives a plant in a loop.

    Attributes:
        inlet, outlet: the valve commands (A).
        reference: the head height asked for (m).
        period_s: the commands' period; every signal but the camera frames is logged at it.
        name: "offset-free-lqg", "paper-lqg" or "excitation".
        controller: the controller's ports, which read the fused estimate and the reference;
            None when nothing closes the loop.
    """

    inlet: OutputPort
    outlet: OutputPort
    reference: OutputPort
    period_s: float
    name: str
    controller: object = None


def assemble_loop(
    builder: DiagramBuilder,
    config: Scenario,
    plant: AddedPlant,
    drive: LoopDrive,
    record: bool,
    diagram_name: str,
    model=None,
    design=None,
) -> ClosedLoop:
    """Finishes a loop around ``plant``: valves driven, head watched, outputs logged, Diagram built.

    ``drive``'s commands go into the valves; the cameras, filters and fusion watch the head (and
    feed the controller, if any); every output is exported and logged; the Diagram is built and
    named.
    """
    # Missed controller ticks (a fault) deliver the last commands again; from here on, the log
    # and the safety supervisor included, the commands are those delivered. Their draws are added
    # after every other source.
    tick_draws = LateRandomSources()
    delivered = add_controller_faults(
        builder, config.faults, drive.inlet, drive.outlet, drive.period_s, tick_draws
    )
    drive = replace(drive, inlet=delivered[0], outlet=delivered[1])
    # The scenario models' RandomSources are added last, so switching one on changes no draw of
    # the others (late_random_sources).
    late = LateRandomSources()
    # The head's height: the bladder's lift plus the patient's own motion, when there is any.
    head_height = add_patient_motion(
        builder, config.patient_motion, plant.head_height, "patient_motion", late
    )
    frames: list[CameraFrame] = []
    sensing = add_sensing_chain(
        builder, config, head_height, plant.start_height_m, frames if record else None, late
    )
    if drive.controller is not None:
        controller = drive.controller
        builder.Connect(
            sensing.fusion.outputs["estimated_state"], controller.inputs["fused_estimated_state"]
        )
        builder.Connect(drive.reference, controller.inputs["reference_head_height_m"])
    logged = {
        "reference_head_height_m": drive.reference,
        "head_height_m": head_height,
        "inlet_valve_current_a": drive.inlet,
        "outlet_valve_current_a": drive.outlet,
    }
    valves = (drive.inlet, drive.outlet)
    if config.safety.enabled and drive.controller is not None:
        safety = _add_supervisor(builder, config, plant, drive, sensing, late)
        valves = (safety.outputs["inlet_valve_current_a"], safety.outputs["outlet_valve_current_a"])
        for port in ("inlet_valve_current_a", "outlet_valve_current_a", *SAFETY_STATUS):
            logged[f"safety.{port}"] = safety.outputs[port]
        logged["safety.estimated_head_height_m"] = drive.controller.outputs[
            "estimated_head_height_m"
        ]
    if plant.gauge_pressure is not None:
        logged["plant.bladder_gauge_pressure_pa"] = plant.gauge_pressure
    # A stuck valve sees its stuck current; the controller and the log see its command.
    ports = (plant.inlet, plant.outlet)
    for valve, command, port in zip(("inlet", "outlet"), valves, ports, strict=True):
        builder.Connect(add_valve_faults(builder, config.faults, valve, command), port)
    loggers = export_and_log(builder, config, sensing, logged, drive.period_s, record)
    late.add_all(builder)
    tick_draws.add_all(builder)
    diagram = builder.Build()
    diagram.set_name(diagram_name)
    return ClosedLoop(
        diagram=diagram,
        plant=kind_name(config.plant),
        controller=drive.name,
        model=model,
        design=design,
        start_height_m=plant.start_height_m,
        sensor_names=sensing.sensor_names,
        loggers=loggers,
        frames=frames,
    )


def _add_supervisor(
    builder, config: Scenario, plant: AddedPlant, drive: LoopDrive, sensing, late
) -> PortMap:
    """The safety supervisor between ``drive``'s commands and the valves (safety_supervisor).

    It reads the bladder's pressure through the pressure sensor (its noise source, if any, waits
    in ``late``).
    """
    p = config.pneumatic
    if plant.gauge_pressure is None:  # a model plant has no bladder: its pressure check never fires
        pressure = builder.AddNamedSystem("no_pressure_sensor", ConstantVectorSource([0.0]))
        pressure = pressure.get_output_port()
    else:
        pressure = add_pressure_sensor(
            builder,
            "bladder_pressure_sensor",
            config.pressure_sensor,
            plant.gauge_pressure,
            drive.period_s,
            late,
        )
    low = p.rest_head_height_m + p.min_lift_m
    high = p.rest_head_height_m + p.max_lift_m
    safety = add_safety_supervisor(
        builder,
        config.safety,
        period_s=drive.period_s,
        camera_count=len(config.cameras),
        head_height_limits_m=(low, high),
        tolerance_m=config.metrics.tolerance_m,
        inlet_saturation_a=p.inlet.saturation_current_a,
        outlet_saturation_a=p.outlet.saturation_current_a,
    )
    reset = builder.AddNamedSystem(SAFETY_RESET_NAME, ConstantVectorSource([0.0]))
    for port, source in (
        ("inlet_command_a", drive.inlet),
        ("outlet_command_a", drive.outlet),
        ("fused_estimated_state", sensing.fusion.outputs["estimated_state"]),
        ("fusion_health", sensing.fusion.outputs["health"]),
        ("reference_head_height_m", drive.reference),
        ("estimated_head_height_m", drive.controller.outputs["estimated_head_height_m"]),
        ("bladder_gauge_pressure_pa", pressure),
        ("reset", reset.get_output_port()),
    ):
        builder.Connect(source, safety.inputs[port])
    return safety


def set_safety_reset(diagram: Diagram, context: Context, raised: bool) -> None:
    """Raises (or lowers) the safety supervisor's reset: at its next tick, every reason clears.

    A latched reason stays until a person resets it, as a real positioner's would: raise the reset,
    simulate past a tick, lower it (a reset held up clears each reason again at every tick).
    """
    source = diagram.GetSubsystemByName(SAFETY_RESET_NAME)
    value = source.get_mutable_source_value(source.GetMyMutableContextFromRoot(context))
    value.set_value([1.0 if raised else 0.0])


def logged_signals(
    closed_loop: ClosedLoop, context, taken: dict | None = None
) -> dict[str, Signal]:
    """Every logged output of ``closed_loop`` in ``context``, by its exported name.

    With ``taken`` (log sink -> samples already taken, updated here), only the samples logged
    since.
    """
    taken = {} if taken is None else taken
    first = {sink: taken.get(sink, 0) for sink, _ in closed_loop.loggers.values()}
    signals = {}
    for name, (sink, rows) in closed_loop.loggers.items():
        log = sink.FindLog(context)
        start = first[sink]
        signals[name] = Signal(log.sample_times()[start:].copy(), log.data()[rows, start:].copy())
        taken[sink] = log.num_samples()
    return signals


def set_plant_parameters(
    diagram: Diagram, context: Context, parameters: PneumaticParameters
) -> None:
    """Writes a pneumatic plant's constants (a drawn head mass) into a built loop's Context.

    The plant then rests at the loop's starting valve currents. A sweep over plants simulates one
    built Diagram instead of building one per draw. Only the plant changes: the reference, and
    the start height the filters and the controller begin from, stay those the loop was built for
    (a heavier head starts lower, and the loop first brings it to the reference). Write after
    ``SetRandomContext`` or ``SetDefaultContext``, which restore the constants the loop was built
    with.

    Args:
        diagram: a closed loop's Diagram (``build_closed_loop``) with the pneumatic plant.
        context: ``diagram``'s Context.
        parameters: the plant's new constants; only the loop's ``plant_context_parameters`` may
            differ from the ones the loop was built with.

    Raises:
        ConfigError: the loop has no pneumatic plant, ``parameters`` changes a constant the plant
            was built with as a number, or ``parameters`` cannot describe a physical plant.
    """
    if not diagram.HasSubsystemNamed(PNEUMATIC_PLANT_NAME):
        raise ConfigError(
            f"{diagram.get_name()}: no {PNEUMATIC_PLANT_NAME!r}; plant parameters can be set only "
            "in a loop around the pneumatic plant"
        )
    set_pneumatic_parameters(diagram, context, parameters, name=PNEUMATIC_PLANT_NAME)
