"""Camera frames as the face detector saw them, and their Foxglove messages.

A ``CameraFrame`` is one colour image with what the detector found in it: the face, the eyes and
the region the depth was read from, as pixel boxes ``(x, y, width, height)`` whose origin is the
image's top-left corner (the convention of OpenCV's detectors and of Foxglove's annotations, so a
box is drawn as it was found), and the distance measured there.

A recording carries each frame as two messages at the frame's simulated time:

- ``/cameras/NAME/image``: a ``foxglove.CompressedImage``, the colour image as JPEG;
- ``/cameras/NAME/annotations``: a ``foxglove.ImageAnnotations``, one outlined box per detection
  (face green, eyes blue, depth region yellow) and a text label with the measurement.

Foxglove draws the annotations over the image. The schemas and the protobuf encoding come from
``foxglove.messages``. So that a frame can be read back whole, each box carries its role in the
annotation's metadata (``"box"``: ``"face"``, ``"eye"`` or ``"depth_region"``) and the message's
metadata carries the measurement (``"distance_m"``, ``"valid"``); ``frame_from_messages`` is the
inverse of ``image_message`` and ``annotations_message``, up to the JPEG's loss.
"""

import math
import re
from dataclasses import dataclass
from numbers import Integral, Real

import cv2
import numpy as np
from foxglove.messages import (
    Color,
    CompressedImage,
    ImageAnnotations,
    KeyValuePair,
    Point2,
    PointsAnnotation,
    PointsAnnotationType,
    TextAnnotation,
    Timestamp,
)

from maskless.sensor_names import is_sensor_name

__all__ = [
    "BOX_COLOURS",
    "JPEG_QUALITY",
    "Box",
    "CameraFrame",
    "annotations_message",
    "annotations_topic",
    "camera_of_topic",
    "frame_from_messages",
    "image_message",
    "image_topic",
]

# Enough to read a face and its boxes by eye, at a tenth of the raw image's size.
JPEG_QUALITY = 85

# RGBA in [0, 1], as both Foxglove and matplotlib take them: face green, eyes blue, region yellow.
BOX_COLOURS: dict[str, tuple[float, float, float, float]] = {
    "face": (0.0, 0.8, 0.0, 1.0),
    "eye": (0.1, 0.4, 1.0, 1.0),
    "depth_region": (1.0, 0.85, 0.0, 1.0),
}
_BOX_THICKNESS_PX = 2.0
_FONT_SIZE_PX = 14.0
_TEXT_COLOUR = Color(r=1.0, g=1.0, b=1.0, a=1.0)
_TEXT_BACKGROUND = Color(r=0.0, g=0.0, b=0.0, a=0.6)

# x, y, width, height in pixels.
Box = tuple[int, int, int, int]

# What image_topic and annotations_topic write, read back.
_CAMERA_TOPIC = re.compile(r"/cameras/([A-Za-z0-9_]+)/(?:image|annotations)")


# eq=False: rgb is an array, so field-wise == and hashing would fail.
@dataclass(frozen=True, eq=False)
class CameraFrame:
    """One camera image as the face detector saw it, with what it found.

    Attributes:
        camera: Camera name, e.g. ``"kinect_v1"`` (letters, digits and underscores: it names the
            camera's topics).
        time_s: Simulated time of the image (s), >= 0.
        rgb: ``(H, W, 3)`` uint8 colour image, channels in RGB order.
        face_box: The face, ``(x, y, width, height)`` in ``rgb`` pixels; None when no face was
            found.
        eye_boxes: Zero to two eye boxes, in the same pixels.
        region_box: Where the depth was read, in the same pixels; None when nowhere.
        distance_m: The measurement (m); nan when not valid.
        valid: Whether ``distance_m`` is a usable measurement (then it is finite).

    Raises:
        ValueError: On construction, if a field is malformed (the message names the field): a
            camera name with other characters, a negative or non-finite time, an image that is not
            ``(H, W, 3)`` uint8, a box that is not a tuple of four integers lying inside the
            image, more than two eyes, or a valid measurement that is not finite.
    """

    camera: str
    time_s: float
    rgb: np.ndarray
    face_box: Box | None
    eye_boxes: tuple[Box, ...]
    region_box: Box | None
    distance_m: float
    valid: bool

    def __post_init__(self):
        """Checks every field, as the class docstring lists."""
        if not is_sensor_name(self.camera):
            raise ValueError(
                f"camera {self.camera!r}: use letters, digits and underscores only "
                "(it names the camera's topics)"
            )
        _check_time(self.time_s)
        _check_rgb(self.rgb)
        height, width = self.rgb.shape[:2]
        if self.face_box is not None:
            _check_box("face_box", self.face_box, width, height)
        if not isinstance(self.eye_boxes, tuple) or len(self.eye_boxes) > 2:
            raise ValueError(f"eye_boxes: expected a tuple of 0 to 2 boxes, got {self.eye_boxes!r}")
        for i, box in enumerate(self.eye_boxes):
            _check_box(f"eye_boxes[{i}]", box, width, height)
        if self.region_box is not None:
            _check_box("region_box", self.region_box, width, height)
        _check_measurement(self.distance_m, self.valid)

    @property
    def time_ns(self) -> int:
        """The simulated time in integer ns, rounded as the recording rounds its log times."""
        return round(self.time_s * 1e9)


def _check_time(time_s) -> None:
    if isinstance(time_s, bool) or not isinstance(time_s, Real) or not time_s >= 0:
        raise ValueError(f"time_s: expected a simulated time >= 0 s, got {time_s!r}")
    if not math.isfinite(time_s):
        raise ValueError(f"time_s: expected a finite time, got {time_s!r}")


def _check_rgb(rgb) -> None:
    if not isinstance(rgb, np.ndarray):
        raise ValueError(f"rgb: expected an (H, W, 3) uint8 array, got {type(rgb).__name__}")
    if rgb.dtype != np.uint8:
        raise ValueError(f"rgb: expected dtype uint8, got {rgb.dtype}")
    if rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.shape[0] == 0 or rgb.shape[1] == 0:
        raise ValueError(f"rgb: expected shape (H, W, 3) with H, W >= 1, got {rgb.shape}")


def _check_box(name: str, box, width: int, height: int) -> None:
    """A box is four integers (x, y, width, height) covering at least one pixel of the image."""
    if (
        not isinstance(box, tuple)
        or len(box) != 4
        or not all(isinstance(v, Integral) and not isinstance(v, bool) for v in box)
    ):
        raise ValueError(f"{name}: expected a tuple of 4 ints (x, y, width, height), got {box!r}")
    x, y, w, h = box
    if x < 0 or y < 0 or w < 1 or h < 1 or x + w > width or y + h > height:
        raise ValueError(
            f"{name}: box {box!r} does not lie inside the {width} x {height} image "
            "(x, y >= 0; width, height >= 1; x + width <= image width, y + height <= image height)"
        )


def _check_measurement(distance_m, valid) -> None:
    if not isinstance(valid, bool | np.bool_):
        raise ValueError(f"valid: expected a bool, got {valid!r}")
    if isinstance(distance_m, bool) or not isinstance(distance_m, Real):
        raise ValueError(f"distance_m: expected a number (m), got {distance_m!r}")
    if valid and not math.isfinite(distance_m):
        raise ValueError(f"distance_m: a valid measurement must be finite, got {distance_m!r}")


def image_topic(name: str) -> str:
    """Returns ``"/cameras/{name}/image"``, the topic of a camera's images.

    Raises:
        ValueError: If ``name`` is not a sensor name (letters, digits and underscores only).
    """
    _check_camera_name(name)
    return f"/cameras/{name}/image"


def annotations_topic(name: str) -> str:
    """Returns ``"/cameras/{name}/annotations"``, the topic of a camera's detections.

    Raises:
        ValueError: If ``name`` is not a sensor name (letters, digits and underscores only).
    """
    _check_camera_name(name)
    return f"/cameras/{name}/annotations"


def camera_of_topic(topic: str) -> str | None:
    """The camera whose image or annotations topic ``topic`` is; None for any other topic."""
    match = _CAMERA_TOPIC.fullmatch(topic)
    return None if match is None else match[1]


def _check_camera_name(name: str) -> None:
    if not is_sensor_name(name):
        raise ValueError(f"invalid camera name {name!r}: use letters, digits and underscores only")


def _timestamp(frame: CameraFrame) -> Timestamp:
    seconds, nanoseconds = divmod(frame.time_ns, 1_000_000_000)
    return Timestamp(seconds, nanoseconds)


def image_message(frame: CameraFrame) -> CompressedImage:
    """The frame's colour image as a JPEG ``foxglove.CompressedImage``.

    ``frame_id`` is the camera's name and ``timestamp`` the simulated time. The same frame always
    gives the same bytes (a fixed quality, no time or randomness in the encoder).
    """
    # OpenCV encodes BGR images.
    ok, jpeg = cv2.imencode(
        ".jpg",
        cv2.cvtColor(frame.rgb, cv2.COLOR_RGB2BGR),
        [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY],
    )
    if not ok:  # OpenCV reports a failed encoding by its flag, not an exception
        raise RuntimeError(f"camera {frame.camera!r}: OpenCV could not encode the image as JPEG")
    return CompressedImage(
        timestamp=_timestamp(frame),
        frame_id=frame.camera,
        data=jpeg.tobytes(),
        format="jpeg",
    )


def _box_annotation(role: str, box: Box) -> PointsAnnotation:
    x, y, w, h = (float(v) for v in box)
    r, g, b, a = BOX_COLOURS[role]
    return PointsAnnotation(
        type=PointsAnnotationType.LineLoop,
        points=[
            Point2(x=x, y=y),
            Point2(x=x + w, y=y),
            Point2(x=x + w, y=y + h),
            Point2(x=x, y=y + h),
        ],
        outline_color=Color(r=r, g=g, b=b, a=a),
        thickness=_BOX_THICKNESS_PX,
        metadata=[KeyValuePair(key="box", value=role)],
    )


def _label(frame: CameraFrame) -> str:
    """``"kinect_v1 832.1 mm"``, or ``"kinect_v1 no measurement"`` when not valid."""
    if not frame.valid:
        return f"{frame.camera} no measurement"
    return f"{frame.camera} {frame.distance_m * 1000:.1f} mm"


def annotations_message(frame: CameraFrame) -> ImageAnnotations:
    """The frame's detections as a ``foxglove.ImageAnnotations`` at the frame's simulated time.

    One outlined box (``LINE_LOOP``) per detection, face first, then the eyes, then the depth
    region; one text label just above the face (at the top-left corner without one).
    """
    boxes = [("face", frame.face_box)] if frame.face_box is not None else []
    boxes += [("eye", box) for box in frame.eye_boxes]
    if frame.region_box is not None:
        boxes.append(("depth_region", frame.region_box))
    # The label's position is its bottom-left corner: above the face, kept inside the image.
    if frame.face_box is not None:
        x, y = float(frame.face_box[0]), max(float(frame.face_box[1]) - 4.0, _FONT_SIZE_PX)
    else:
        x, y = 4.0, 4.0 + _FONT_SIZE_PX
    label = TextAnnotation(
        position=Point2(x=x, y=y),
        text=_label(frame),
        font_size=_FONT_SIZE_PX,
        text_color=_TEXT_COLOUR,
        background_color=_TEXT_BACKGROUND,
    )
    return ImageAnnotations(
        timestamp=_timestamp(frame),
        points=[_box_annotation(role, box) for role, box in boxes],
        texts=[label],
        metadata=[
            # repr: the shortest text that reads back as the same float ("nan" included).
            KeyValuePair(key="distance_m", value=repr(float(frame.distance_m))),
            KeyValuePair(key="valid", value="true" if frame.valid else "false"),
        ],
    )


def frame_from_messages(camera: str, image, annotations) -> CameraFrame:
    """The frame a camera's image and annotations messages carry (their inverse, but the JPEG's).

    Args:
        camera: The camera's name (the one in the messages' topics).
        image: A decoded ``foxglove.CompressedImage`` protobuf message (as ``mcap_protobuf``'s
            decoder gives it).
        annotations: The decoded ``foxglove.ImageAnnotations`` of the same image.

    Returns:
        The frame, its ``rgb`` decoded from the JPEG (so within JPEG error of what was written),
        its time that of the image's timestamp.

    Raises:
        ValueError: If the image cannot be decoded, or the annotations lack a measurement or
            hold a box of unknown role.
    """
    pixels = cv2.imdecode(np.frombuffer(image.data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if pixels is None:
        raise ValueError(f"camera {camera!r}: image data is not an image OpenCV can decode")
    boxes: dict[str, list[Box]] = {role: [] for role in BOX_COLOURS}
    for annotation in annotations.points:
        role = {item.key: item.value for item in annotation.metadata}.get("box")
        if role not in boxes:
            raise ValueError(f"camera {camera!r}: annotation box role {role!r} is not one of ours")
        boxes[role].append(_box_of(annotation.points))
    measurement = {item.key: item.value for item in annotations.metadata}
    if "distance_m" not in measurement or "valid" not in measurement:
        raise ValueError(f"camera {camera!r}: annotations carry no distance_m and valid metadata")
    return CameraFrame(
        camera=camera,
        time_s=(image.timestamp.seconds * 1_000_000_000 + image.timestamp.nanos) / 1e9,
        rgb=cv2.cvtColor(pixels, cv2.COLOR_BGR2RGB),
        face_box=boxes["face"][0] if boxes["face"] else None,
        eye_boxes=tuple(boxes["eye"]),
        region_box=boxes["depth_region"][0] if boxes["depth_region"] else None,
        distance_m=float(measurement["distance_m"]),
        valid=measurement["valid"] == "true",
    )


def _box_of(points) -> Box:
    """The (x, y, width, height) box whose outline ``points`` are."""
    xs, ys = [round(p.x) for p in points], [round(p.y) for p in points]
    return min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys)
