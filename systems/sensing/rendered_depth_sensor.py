"""A depth camera that measures by rendering: Drake's RgbdSensor, then face detection on its images.

Per frame: the camera renders colour and depth of the scene (``camera_scene``); the depth image gets
the Kinect's per-pixel noise, quantisation and holes (``depth_image_noise``); the face and eyes are
found in the colour image and the face's distance read in the depth image (``face_detection``).
The result goes out on the measurement model's port contract (``distance_m``, ``valid``), so the
local filters, the fusion and the controller are the same for both fidelities.

Timing is the measurement model's: a frame is rendered at each frame tick and its measurement
reaches the filter at the filter's next tick, one frame later; a configured latency of more frames
holds it longer. Randomness comes from a RandomSource (``{name}.seed``) that draws the camera's seed
at t = 0 (as every RandomSource draws at its first tick) and never again within a run; each
frame's noise is drawn from the stream numpy's SeedSequence makes of that seed and the frame's
index. So a run seeded with ``diagram.SetRandomContext`` is reproducible bit for bit, and after
t = 0 the seed does not change: the frame recorder, whose publish at a frame tick comes just
before the tick's update, reads the very measurement the update takes (Drake's cache serves both),
and each frame is rendered and searched once, recorded or not.
"""

import math
from collections.abc import Callable

import cv2
import numpy as np
from pydrake.common import RandomDistribution
from pydrake.common.value import AbstractValue
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    RenderCameraCore,
)
from pydrake.math import RigidTransform
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import RandomSource
from pydrake.systems.sensors import CameraInfo, ImageDepth32F, ImageRgba8U, RgbdSensor

from maskless.systems.named_symbolic_system import PortMap
from maskless.systems.sensing.camera_scene import RENDERER, CameraScene, camera_pose
from maskless.systems.sensing.depth_image_noise import kinect_depth_image
from maskless.systems.sensing.depth_sensor import (
    DepthSensorConfig,
    latency_frames,
    validate_sensor_config,
)
from maskless.systems.sensing.face_detection import (
    Box,
    FaceFinder,
    FaceMeasurement,
    find_face_region,
    invalid_measurement,
    map_box,
    region_distance_m,
    with_distance,
)

# The renderer's clipping planes (m); the camera's working range is applied to the depth image.
CLIPPING_RANGE_M = (0.05, 10.0)
# A uniform draw in [0, 1) becomes a 53-bit seed (a double's significand) for the camera's noise.
_SEED_BITS = 53
# The seed's RandomSource is a sampler like any other; with this period (s) it samples at t = 0
# and never again within a run, so one seed serves a whole run.
_SEED_HOLD_S = 1.0e12

# Tracker state: the last face box (x, y, width, height), then whether there was one.
_TRACK_SIZE = 5
_TRACK_FOUND = 4


def frame_index(time_s: float, period_s: float) -> int:
    """The index of the frame ticked at ``time_s`` (0 at t = 0)."""
    return round(time_s / period_s)


def measure_frame(
    finder: FaceFinder,
    config: DepthSensorConfig,
    color_rgba: np.ndarray,
    depth_m: np.ndarray,
    last_face: Box | None,
    rng: np.random.Generator | None,
    time_s: float,
) -> FaceMeasurement:
    """One frame's measurement: dropout, face and eyes, then the eye band's noisy depth.

    Args:
        finder: the cascades.
        config: the camera (dropout, noise, range).
        color_rgba: the colour image, (rows, columns, 4) uint8, at ``rendering.color_scale``.
        depth_m: the exact depth image (m), (rows, columns), at the camera's resolution.
        last_face: where the face was in the last frame (colour pixels), or None.
        rng: the frame's random stream; None for a perfect camera of this model (no dropped
            frame, no noise, no lost pixel; still quantised and range-limited).
        time_s: the frame's time (s), for the warm-up drift.
    """
    if rng is not None and rng.random() < config.dropout_probability:
        return invalid_measurement("frame dropped")
    found = find_face_region(finder, cv2.cvtColor(color_rgba, cv2.COLOR_RGBA2GRAY), last_face)
    if not found.valid:
        return found
    # The region in depth pixels, from the two images' actual sizes.
    factors = (
        depth_m.shape[1] / color_rgba.shape[1],
        depth_m.shape[0] / color_rgba.shape[0],
    )
    x, y, w, h = map_box(found.region_box, factors, depth_m.shape)
    # Only the region's pixels are read, so only they get the camera's noise, drawn as for a
    # whole noisy image, for a fraction of the cost.
    region = kinect_depth_image(depth_m[y : y + h, x : x + w], config, time_s, rng)
    return with_distance(found, region_distance_m(region))


def camera_info(config: DepthSensorConfig, scale: float = 1.0) -> CameraInfo:
    """The camera's intrinsics (image size, fields of view, centred principal point), scaled.

    ``scale`` < 1 gives the same view in fewer pixels: the camera's image downsampled.
    """
    rendering = config.rendering
    width = round(rendering.image_width_px * scale)
    height = round(rendering.image_height_px * scale)
    focal_x = width / 2 / math.tan(math.radians(rendering.horizontal_fov_deg) / 2)
    focal_y = height / 2 / math.tan(math.radians(rendering.vertical_fov_deg) / 2)
    return CameraInfo(width, height, focal_x, focal_y, (width - 1) / 2, (height - 1) / 2)


def make_rgbd_sensor(scene: CameraScene, config: DepthSensorConfig) -> RgbdSensor:
    """Drake's RgbdSensor for ``config``'s camera, mounted as configured, looking down.

    Depth at the camera's resolution; colour at ``rendering.color_scale`` of it, the same view.
    """

    def core(scale):
        return RenderCameraCore(
            RENDERER,
            camera_info(config, scale),
            ClippingRange(*CLIPPING_RANGE_M),
            RigidTransform(),
        )

    return RgbdSensor(
        scene.world_frame,
        camera_pose(config.rendering.position_m, config.mount_height_m),
        ColorRenderCamera(core(config.rendering.color_scale), False),
        DepthRenderCamera(core(1.0), DepthRange(*CLIPPING_RANGE_M)),
    )


def add_rgbd_sensor(
    builder: DiagramBuilder, name: str, scene: CameraScene, config: DepthSensorConfig
) -> RgbdSensor:
    """Adds ``config``'s RgbdSensor as ``{name}.camera``, reading ``scene``'s geometry."""
    camera = builder.AddNamedSystem(f"{name}.camera", make_rgbd_sensor(scene, config))
    builder.Connect(scene.scene_graph.get_query_output_port(), camera.query_object_input_port())
    return camera


class FaceDepthSensor(LeafSystem):
    """Measures the camera-to-face distance in a camera's images, once per frame.

    .. pydrake_system::

        name: kinect_v1
        input_ports:
        - color_image
        - depth_image
        - seed
        output_ports:
        - distance_m
        - valid
        - measurement

    ``measurement`` is the frame being taken now (a ``FaceMeasurement``: boxes, distance and why
    not, from the current images); ``distance_m`` and ``valid`` are the last frame's, as its
    filter receives them.

    Args:
        config: the camera (its noise, range, latency and ``rendering`` settings).
    """

    def __init__(self, config: DepthSensorConfig):
        """Declares the ports, the tracker and measurement state, and the frame tick."""
        super().__init__()
        self._config = config
        self._finder = FaceFinder()
        self._color = self.DeclareAbstractInputPort(
            "color_image", AbstractValue.Make(ImageRgba8U())
        )
        self._depth = self.DeclareAbstractInputPort(
            "depth_image", AbstractValue.Make(ImageDepth32F())
        )
        self._seed = self.DeclareVectorInputPort("seed", 1)
        self._period_s = 1.0 / config.frame_rate_hz
        self._track = self.DeclareDiscreteState(_TRACK_SIZE)
        # (distance, valid) per frame still on its way, newest first; the last pair is output.
        self._pipeline = self.DeclareDiscreteState(2 * latency_frames(config))
        self.DeclareVectorOutputPort("distance_m", 1, self._calc_distance)
        self.DeclareVectorOutputPort("valid", 1, self._calc_valid)
        self._measurement = self.DeclareAbstractOutputPort(
            "measurement",
            lambda: AbstractValue.Make(invalid_measurement("no frame yet")),
            self._calc_measurement,
        )
        self.DeclarePeriodicDiscreteUpdateEvent(self._period_s, 0.0, self._take_frame)

    def _calc_measurement(self, context, output) -> None:
        time_s = context.get_time()
        seed = int(self._seed.Eval(context)[0] * 2**_SEED_BITS)
        rng = np.random.default_rng([seed, frame_index(time_s, self._period_s)])
        track = context.get_discrete_state(self._track).value()
        last_face = tuple(int(v) for v in track[:4]) if track[_TRACK_FOUND] > 0.5 else None
        color = self._color.Eval(context).data
        depth = self._depth.Eval(context).data[:, :, 0]
        output.set_value(
            measure_frame(self._finder, self._config, color, depth, last_face, rng, time_s)
        )

    def _take_frame(self, context, discrete_state) -> None:
        measurement: FaceMeasurement = self._measurement.Eval(context)
        track = discrete_state.get_mutable_vector(self._track)
        if measurement.face_box is not None:
            track.SetFromVector([*measurement.face_box, 1.0])
        elif measurement.reason != "frame dropped":
            track.SetAtIndex(_TRACK_FOUND, 0.0)  # lost: search the whole image next frame
        pipeline = context.get_discrete_state(self._pipeline).value()
        distance = measurement.distance_m if measurement.valid else 0.0
        discrete_state.get_mutable_vector(self._pipeline).SetFromVector(
            np.concatenate([[distance, float(measurement.valid)], pipeline[:-2]])
        )

    def _calc_distance(self, context, output) -> None:
        output.SetAtIndex(0, context.get_discrete_state(self._pipeline).value()[-2])

    def _calc_valid(self, context, output) -> None:
        output.SetAtIndex(0, context.get_discrete_state(self._pipeline).value()[-1])


FrameSink = Callable[[str, float, np.ndarray, FaceMeasurement], None]


class FrameRecorder(LeafSystem):
    """Hands every ``decimation``-th frame of a camera, with what was found in it, to ``sink``.

    A publish event (a side effect only) at the sensor's own frame ticks (the same period and
    offset, so the same instants to the last bit), so it reads the very render and the very
    measurement the sensor's update takes at that tick. Recording starts at the second frame: at
    the first, the seed's RandomSource draws (as every RandomSource does at t = 0) between the
    publish and the update, so the two would see different noise.

    .. pydrake_system::

        name: kinect_v1.frames
        input_ports:
        - color_image
        - measurement

    Args:
        camera: the camera's name, passed to ``sink``.
        period_s: the camera's frame period (s).
        decimation: frames per recorded frame.
        sink: called as sink(camera, time_s, rgb, measurement) with a copy of the image.
    """

    def __init__(self, camera: str, period_s: float, decimation: int, sink: FrameSink):
        """Declares the inputs and the periodic publish."""
        super().__init__()
        self._camera = camera
        self._sink = sink
        self._color = self.DeclareAbstractInputPort(
            "color_image", AbstractValue.Make(ImageRgba8U())
        )
        self._measurement = self.DeclareAbstractInputPort(
            "measurement", AbstractValue.Make(invalid_measurement("no frame yet"))
        )
        self._period_s = period_s
        self._decimation = decimation
        self.DeclarePeriodicPublishEvent(period_s, 0.0, self._record)

    def _record(self, context) -> None:
        index = frame_index(context.get_time(), self._period_s)
        if index < 1 or (index - 1) % self._decimation:
            return
        measurement = self._measurement.Eval(context)
        rgb = self._color.Eval(context).data[:, :, :3].copy()
        self._sink(self._camera, context.get_time(), rgb, measurement)


def add_rendered_depth_sensor(
    builder: DiagramBuilder,
    name: str,
    config: DepthSensorConfig,
    scene: CameraScene,
    frame_sink: FrameSink | None = None,
    record_every_frames: int = 1,
) -> PortMap:
    """Adds a rendered camera watching ``scene``: ``name.camera``, ``name.seed``, ``name``.

    .. pydrake_system::

        name: kinect_v1
        output_ports:
        - distance_m
        - valid

    Args:
        builder: where the systems go.
        name: the camera's name (and its measurement's name in recordings).
        config: the camera, with ``rendering`` enabled.
        scene: the scene it looks at (``camera_scene.add_camera_scene``).
        frame_sink: when given, every ``record_every_frames``-th frame goes to it
            (``FrameRecorder``, ``name.frames``).
        record_every_frames: frames per recorded frame.
    """
    validate_sensor_config(name, config)
    period_s = 1.0 / config.frame_rate_hz
    camera = add_rgbd_sensor(builder, name, scene, config)
    seed = builder.AddNamedSystem(
        f"{name}.seed", RandomSource(RandomDistribution.kUniform, 1, _SEED_HOLD_S)
    )
    sensor = builder.AddNamedSystem(name, FaceDepthSensor(config))
    builder.Connect(camera.color_image_output_port(), sensor.GetInputPort("color_image"))
    builder.Connect(camera.depth_image_32F_output_port(), sensor.GetInputPort("depth_image"))
    builder.Connect(seed.get_output_port(), sensor.GetInputPort("seed"))
    if frame_sink is not None:
        recorder = builder.AddNamedSystem(
            f"{name}.frames", FrameRecorder(name, period_s, record_every_frames, frame_sink)
        )
        builder.Connect(camera.color_image_output_port(), recorder.GetInputPort("color_image"))
        builder.Connect(sensor.GetOutputPort("measurement"), recorder.GetInputPort("measurement"))
    return PortMap(
        outputs={
            "distance_m": sensor.GetOutputPort("distance_m"),
            "valid": sensor.GetOutputPort("valid"),
        }
    )
