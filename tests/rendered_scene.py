"""A scene with the shipped cameras rendering it, the head height an input: for rendering tests."""

from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import PassThrough

from maskless.diagrams.scenario import load_scenario
from maskless.systems.sensing.camera_scene import add_camera_scene
from maskless.systems.sensing.rendered_depth_sensor import add_rgbd_sensor


@dataclass
class RenderedScene:
    diagram: object
    context: object
    cameras: dict  # name -> (config, RgbdSensor)

    def render(self, name: str, head_height_m: float):
        """(rgba, depth) of camera ``name`` with the head at ``head_height_m``."""
        self.diagram.get_input_port(0).FixValue(self.context, [head_height_m])
        config, sensor = self.cameras[name]
        context = sensor.GetMyContextFromRoot(self.context)
        rgba = sensor.color_image_output_port().Eval(context).data.copy()
        depth = sensor.depth_image_32F_output_port().Eval(context).data[:, :, 0].copy()
        return rgba, depth


def shipped_cameras(**rendering_changes):
    """The shipped cameras, rendered, with ``rendering_changes`` applied to each."""
    cameras = load_scenario().cameras
    for camera in cameras.values():
        camera.rendering.enabled = True
        for key, value in rendering_changes.items():
            setattr(camera.rendering, key, value)
    return cameras


def build_rendered_scene(cameras) -> RenderedScene:
    builder = DiagramBuilder()
    # The scene's pose needs an output port: the exported head height passed through.
    head = builder.AddSystem(PassThrough(1))
    builder.ExportInput(head.get_input_port(), "head_height_m")
    scene = add_camera_scene(builder, head.get_output_port())
    sensors = {}
    for name, config in cameras.items():
        sensors[name] = (config, add_rgbd_sensor(builder, name, scene, config))
    diagram = builder.Build()
    return RenderedScene(diagram, diagram.CreateDefaultContext(), sensors)


# The lift the valves can hold: `maskless analyze operating-range` finds the inlet spans 0-18.11 mm.
WORKING_LIFT_M = (0.0, 0.009, 0.018)


def head_travel_m() -> np.ndarray:
    """The lowest, middle and highest head heights of the pneumatic plant's working range (m)."""
    return load_scenario().pneumatic.rest_head_height_m + np.array(WORKING_LIFT_M)
