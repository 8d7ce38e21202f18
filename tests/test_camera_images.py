"""Tests for maskless.camera_images: frames, their checks, and their Foxglove messages.

Messages are decoded independently (``mcap_protobuf``, Pillow; see ``camera_frames``) and compared
with what went in.
"""

import math

import numpy as np
import pytest
from camera_frames import (
    EYES,
    FACE,
    HEIGHT,
    REGION,
    WIDTH,
    boxes_by_role,
    decode_annotations,
    decode_image,
    empty_frame,
    face_frame,
    gradient_image,
    jpeg_pixels,
    mean_abs_difference,
)
from foxglove.messages import CompressedImage, ImageAnnotations

from maskless.camera_images import (
    CameraFrame,
    annotations_message,
    annotations_topic,
    camera_of_topic,
    frame_from_messages,
    image_message,
    image_topic,
)

# JPEG at quality 85 of a smooth gradient: a mean error of a grey level or two at most.
JPEG_MEAN_ERROR = 2.0


def test_topics_name_the_camera():
    assert image_topic("kinect_v1") == "/cameras/kinect_v1/image"
    assert annotations_topic("zed_2") == "/cameras/zed_2/annotations"
    for topic in (image_topic, annotations_topic):
        with pytest.raises(ValueError, match="camera name 'a/b'"):
            topic("a/b")
        assert camera_of_topic(topic("zed_2")) == "zed_2"
    for other in ("/sensors/zed_2/measurement", "/cameras/zed_2/depth", "/cameras/a/b/image"):
        assert camera_of_topic(other) is None


def test_image_message_is_the_frame_as_jpeg_at_its_time():
    frame = face_frame(time_s=12.345678901)
    message = image_message(frame)
    assert isinstance(message, CompressedImage)
    decoded = decode_image(message.encode())
    assert decoded.format == "jpeg"
    assert decoded.frame_id == "kinect_v1"
    assert (decoded.timestamp.seconds, decoded.timestamp.nanos) == (12, 345_678_901)
    pixels = jpeg_pixels(decoded.data)
    assert pixels.shape == (HEIGHT, WIDTH, 3)
    assert mean_abs_difference(pixels, frame.rgb) < JPEG_MEAN_ERROR
    # Channels in RGB order: a red-only image decodes red, not blue.
    red = np.zeros((HEIGHT, WIDTH, 3), np.uint8)
    red[..., 0] = 255
    red_frame = CameraFrame("kinect_v1", 0.0, red, None, (), None, math.nan, False)
    assert jpeg_pixels(decode_image(image_message(red_frame).encode()).data)[..., 0].min() > 240


def test_annotations_outline_each_box_in_its_colour():
    frame = face_frame(time_s=3.5)
    message = annotations_message(frame)
    assert isinstance(message, ImageAnnotations)
    decoded = decode_annotations(message.encode())
    assert (decoded.timestamp.seconds, decoded.timestamp.nanos) == (3, 500_000_000)
    assert boxes_by_role(decoded) == {"face": [FACE], "eye": list(EYES), "depth_region": [REGION]}
    line_loop = type(decoded.points[0]).LINE_LOOP
    face, *_ = decoded.points
    x, y, w, h = FACE
    assert [(p.x, p.y) for p in face.points] == [(x, y), (x + w, y), (x + w, y + h), (x, y + h)]
    colours = {}
    for outline in decoded.points:
        assert outline.type == line_loop
        assert outline.thickness >= 1
        role = outline.metadata[0].value
        colours[role] = (outline.outline_color.r, outline.outline_color.g, outline.outline_color.b)
    r, g, b = colours["face"]
    assert g > 0.5 > max(r, b)  # green
    r, g, b = colours["eye"]
    assert b > 0.5 > max(r, g)  # blue
    r, g, b = colours["depth_region"]
    assert min(r, g) > 0.5 > b  # yellow
    (label,) = decoded.texts
    assert label.text == "kinect_v1 832.1 mm"
    # Near the face: at its left edge, just above it.
    assert label.position.x == x and y - 20 <= label.position.y <= y


def test_annotations_of_a_frame_without_a_face_say_no_measurement():
    decoded = decode_annotations(annotations_message(empty_frame()).encode())
    assert list(decoded.points) == []
    (label,) = decoded.texts
    assert label.text == "kinect_v1 no measurement"
    assert label.position.x < 10 and label.position.y < 30  # the top-left corner


def test_the_same_frame_gives_the_same_bytes():
    a, b = face_frame(), face_frame()
    assert image_message(a).encode() == image_message(b).encode()
    assert annotations_message(a).encode() == annotations_message(b).encode()
    other = face_frame(shift=7)
    assert image_message(other).encode() != image_message(a).encode()


@pytest.mark.parametrize("frame", [face_frame(), empty_frame()], ids=["face", "empty"])
def test_messages_read_back_as_the_frame(frame):
    image = decode_image(image_message(frame).encode())
    annotations = decode_annotations(annotations_message(frame).encode())
    back = frame_from_messages(frame.camera, image, annotations)
    assert back.camera == frame.camera
    assert back.time_s == frame.time_s
    assert (back.face_box, back.eye_boxes, back.region_box) == (
        frame.face_box,
        frame.eye_boxes,
        frame.region_box,
    )
    assert back.valid == frame.valid
    np.testing.assert_equal(back.distance_m, frame.distance_m)  # nan equals nan here
    assert back.rgb.dtype == np.uint8 and back.rgb.shape == frame.rgb.shape
    assert mean_abs_difference(back.rgb, jpeg_pixels(image.data)) < 1.0  # Pillow agrees


def test_time_ns_rounds_to_the_nearest_nanosecond():
    assert face_frame(time_s=0.1).time_ns == 100_000_000
    assert face_frame(time_s=1 / 3).time_ns == 333_333_333
    assert face_frame(time_s=2.0000000006).time_ns == 2_000_000_001


def _frame(**changes):
    fields = {
        "camera": "kinect_v1",
        "time_s": 0.5,
        "rgb": gradient_image(),
        "face_box": FACE,
        "eye_boxes": EYES,
        "region_box": REGION,
        "distance_m": 0.8,
        "valid": True,
    }
    return CameraFrame(**{**fields, **changes})


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"camera": "kinect v1"}, "camera 'kinect v1'"),
        ({"camera": ""}, "camera ''"),
        ({"time_s": -0.1}, "time_s"),
        ({"time_s": math.nan}, "time_s"),
        ({"time_s": math.inf}, "time_s"),
        ({"time_s": "0.5"}, "time_s"),
        ({"rgb": gradient_image().astype(np.float32)}, "rgb: expected dtype uint8"),
        ({"rgb": gradient_image()[..., 0]}, r"rgb: expected shape \(H, W, 3\)"),
        ({"rgb": np.zeros((4, 4, 4), np.uint8)}, r"rgb: expected shape"),
        ({"rgb": np.zeros((0, 4, 3), np.uint8)}, r"rgb: expected shape"),
        ({"rgb": [[[0, 0, 0]]]}, "rgb: expected an"),
        ({"face_box": [40, 20, 50, 60]}, "face_box: expected a tuple of 4 ints"),
        ({"face_box": (40, 20, 50)}, "face_box: expected a tuple of 4 ints"),
        ({"face_box": (40.0, 20, 50, 60)}, "face_box: expected a tuple of 4 ints"),
        ({"face_box": (100, 20, 50, 60)}, "face_box: box .* inside the 128 x 96 image"),
        ({"face_box": (-1, 20, 50, 60)}, "face_box: box"),
        ({"face_box": (40, 20, 0, 60)}, "face_box: box"),
        ({"eye_boxes": EYES + EYES[:1]}, "eye_boxes: expected a tuple of 0 to 2 boxes"),
        ({"eye_boxes": list(EYES)}, "eye_boxes: expected a tuple"),
        ({"eye_boxes": (EYES[0], (0, 90, 10, 10))}, r"eye_boxes\[1\]: box"),
        ({"region_box": (0, 0, 129, 1)}, "region_box: box"),
        ({"valid": 1}, "valid: expected a bool"),
        ({"distance_m": None}, "distance_m: expected a number"),
        ({"distance_m": math.nan}, "distance_m: a valid measurement must be finite"),
    ],
)
def test_a_malformed_field_is_refused_by_name(changes, match):
    with pytest.raises(ValueError, match=match):
        _frame(**changes)


def test_numpy_integers_and_bools_are_accepted():
    # What OpenCV's detectors and numpy comparisons hand back.
    face = tuple(np.int32(v) for v in FACE)
    frame = _frame(face_box=face, valid=np.bool_(True), distance_m=np.float32(0.8))
    decoded = decode_annotations(annotations_message(frame).encode())
    assert boxes_by_role(decoded)["face"] == [FACE]
    assert decoded.texts[0].text == "kinect_v1 800.0 mm"
