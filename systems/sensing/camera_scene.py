"""The scene the rendered cameras see: table, bladder and the mannequin's head, in a SceneGraph.

The head is a SceneGraph frame posed from the plant's ``head_height_m`` port, not a MultibodyPlant
body: the plant's own model (pneumatic or identified) already says where the head is, and a
MultibodyPlant would add a second dynamics solve whose only job would be to copy that height. The
face is a textured relief mesh (``assets/face``) whose zero is its eye band, face up at the head
height, so the distance a depth camera should report in the eye band is
``mount_height_m - head_height_m``.

Rendering uses Drake's VTK engine through EGL, so it runs headless, with no X display, on a CPU.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    Box,
    Ellipsoid,
    FrameId,
    FramePoseVector,
    GeometryFrame,
    GeometryInstance,
    MakeRenderEngineVtk,
    Mesh,
    PerceptionProperties,
    RenderEngineVtkParams,
    RenderLabel,
    Rgba,
    SceneGraph,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.framework import DiagramBuilder, LeafSystem, OutputPort

from maskless.systems.config_loading import asset_path

RENDERER = "vtk"
FACE_MESH = "face/face.obj"
# The paper's bladder is 19" x 12" (Sec. II); drawn 2 cm thick on the table, visual only.
BLADDER_SIZE_M = (0.3048, 0.4826, 0.02)
TABLE_SIZE_M = (0.8, 1.2, 0.04)
# A head's back lies about 0.19 m below its face; the skull is drawn just under the face quad.
SKULL_SEMI_AXES_M = (0.075, 0.1, 0.09)
SKULL_BELOW_FACE_M = 0.095


@dataclass
class CameraScene:
    """The scene added to a builder.

    Attributes:
        scene_graph: the SceneGraph whose query port the cameras read.
        world_frame: the table frame (z up from the table top, y towards the top of the head).
    """

    scene_graph: SceneGraph
    world_frame: FrameId


class HeadPose(LeafSystem):
    """Places the head frame at the plant's head height above the table.

    .. pydrake_system::

        name: head_pose
        input_ports:
        - head_height_m
        output_ports:
        - geometry_pose
    """

    def __init__(self, head_frame: FrameId):
        """Poses ``head_frame`` (registered with the SceneGraph by ``add_camera_scene``)."""
        super().__init__()
        self._head_frame = head_frame
        self._height = self.DeclareVectorInputPort("head_height_m", 1)
        self.DeclareAbstractOutputPort(
            "geometry_pose", lambda: AbstractValue.Make(FramePoseVector()), self._calc_pose
        )

    def _calc_pose(self, context, output) -> None:
        poses = FramePoseVector()
        height = self._height.Eval(context)[0]
        poses.set_value(self._head_frame, RigidTransform([0.0, 0.0, height]))
        output.set_value(poses)


def _visual(rgba: Rgba | None = None) -> PerceptionProperties:
    properties = PerceptionProperties()
    properties.AddProperty("label", "id", RenderLabel(1))
    if rgba is not None:
        properties.AddProperty("phong", "diffuse", rgba)
    return properties


def _add_geometry(scene_graph, source, frame, name, shape, pose, rgba=None) -> None:
    instance = GeometryInstance(pose, shape, name)
    instance.set_perception_properties(_visual(rgba))
    if frame is None:
        scene_graph.RegisterAnchoredGeometry(source, instance)
    else:
        scene_graph.RegisterGeometry(source, frame, instance)


def add_camera_scene(builder: DiagramBuilder, head_height: OutputPort) -> CameraScene:
    """Adds the SceneGraph (``scene_graph``) with its VTK renderer, and ``head_pose``.

    Args:
        builder: where the systems go.
        head_height: the plant's head height above the table (m), which poses the head.
    """
    scene_graph = builder.AddNamedSystem("scene_graph", SceneGraph())
    scene_graph.AddRenderer(RENDERER, MakeRenderEngineVtk(RenderEngineVtkParams(backend="EGL")))
    source = scene_graph.RegisterSource("positioner")
    table_top = RigidTransform([0.0, 0.0, -TABLE_SIZE_M[2] / 2])
    _add_geometry(
        scene_graph, source, None, "table", Box(*TABLE_SIZE_M), table_top, Rgba(0.45, 0.45, 0.5)
    )
    bladder = RigidTransform([0.0, 0.0, BLADDER_SIZE_M[2] / 2])
    _add_geometry(
        scene_graph, source, None, "bladder", Box(*BLADDER_SIZE_M), bladder, Rgba(0.3, 0.5, 0.8)
    )
    head = scene_graph.RegisterFrame(source, GeometryFrame("head"))
    face = Mesh(str(asset_path(FACE_MESH)))
    _add_geometry(scene_graph, source, head, "face", face, RigidTransform())
    skull = RigidTransform([0.0, 0.0, -SKULL_BELOW_FACE_M])
    _add_geometry(
        scene_graph,
        source,
        head,
        "skull",
        Ellipsoid(*SKULL_SEMI_AXES_M),
        skull,
        Rgba(0.85, 0.72, 0.62),
    )
    pose = builder.AddNamedSystem("head_pose", HeadPose(head))
    builder.Connect(head_height, pose.get_input_port())
    builder.Connect(pose.get_output_port(), scene_graph.get_source_pose_port(source))
    return CameraScene(scene_graph, scene_graph.world_frame_id())


def camera_pose(position_m, mount_height_m: float) -> RigidTransform:
    """A camera at ``position_m`` ([x, y]), ``mount_height_m`` up, looking straight down.

    Image right is the table's +x and image down its -y, so the face (top of the head towards +y)
    appears upright, as the frontal-face cascade needs.
    """
    rotation = np.diag([1.0, -1.0, -1.0])  # camera z down, camera y (image down) along -y
    return RigidTransform(RotationMatrix(rotation), [*position_m, mount_height_m])
