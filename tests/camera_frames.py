"""Synthetic camera frames for the tests, and the foxglove messages decoded independently.

Messages are decoded by ``mcap_protobuf`` from the schema Foxglove ships, and JPEG images by
Pillow (matplotlib's image dependency), never by the code under test.
"""

import io

import numpy as np
from foxglove.messages import CompressedImage, ImageAnnotations
from mcap.records import Schema
from mcap_protobuf.decoder import DecoderFactory
from PIL import Image

from maskless.camera_images import CameraFrame

HEIGHT, WIDTH = 96, 128
FACE = (40, 20, 50, 60)
EYES = ((48, 35, 12, 8), (70, 35, 12, 8))
REGION = (55, 55, 20, 12)


def gradient_image(shift: int = 0) -> np.ndarray:
    """A smooth RGB gradient (JPEG keeps it well); ``shift`` moves it, to tell frames apart."""
    y, x = np.mgrid[0:HEIGHT, 0:WIDTH]
    red = (x + shift) * 255 // (WIDTH + shift)
    green = y * 255 // HEIGHT
    blue = 255 - (x + y) * 255 // (WIDTH + HEIGHT)
    return np.stack([red, green, blue], axis=-1).astype(np.uint8)


def face_frame(camera="kinect_v1", time_s=0.5, distance_m=0.8321, shift=0) -> CameraFrame:
    """A frame with a face, two eyes and a valid measurement."""
    return CameraFrame(camera, time_s, gradient_image(shift), FACE, EYES, REGION, distance_m, True)


def empty_frame(camera="kinect_v1", time_s=0.6) -> CameraFrame:
    """A frame in which nothing was found."""
    return CameraFrame(camera, time_s, gradient_image(), None, (), None, float("nan"), False)


def _decoder(message_class):
    schema = message_class.get_schema()
    mcap_schema = Schema(id=1, name=schema.name, encoding=schema.encoding, data=bytes(schema.data))
    return DecoderFactory().decoder_for("protobuf", mcap_schema)


decode_image = _decoder(CompressedImage)
decode_annotations = _decoder(ImageAnnotations)


def jpeg_pixels(data: bytes) -> np.ndarray:
    """An (H, W, 3) uint8 RGB array of a JPEG file's bytes, decoded by Pillow."""
    with Image.open(io.BytesIO(data)) as image:
        assert image.format == "JPEG"
        return np.asarray(image.convert("RGB"))


def boxes_by_role(annotations) -> dict[str, list[tuple[int, int, int, int]]]:
    """Each outline's (x, y, width, height), from its corner points, by its metadata role."""
    boxes: dict[str, list[tuple[int, int, int, int]]] = {}
    for outline in annotations.points:
        xs = [p.x for p in outline.points]
        ys = [p.y for p in outline.points]
        role = {item.key: item.value for item in outline.metadata}["box"]
        box = (min(xs), min(ys), max(xs) - min(xs), max(ys) - min(ys))
        boxes.setdefault(role, []).append(tuple(int(v) for v in box))
    return boxes


def mean_abs_difference(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(int) - b.astype(int)).mean())
