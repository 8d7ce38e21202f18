"""Finding the face and its eyes in a camera image, and reading the face's depth (paper Sec. III-A).

As in the paper: Viola-Jones Haar cascades (OpenCV's stock frontal-face and eye cascades) find the
face in a downsampled grey image, then the eyes within the face (enlarged again, where the eyes
would be smaller than the eye cascade needs). As a tracker would, the face is
first searched for near where it was in the last frame, at about its last size, and the whole image
is searched only when that fails.

The depth is read in the eye band, the box spanning both eyes: inside the face by construction,
away from the hair and background at the face box's corners. A face without both eyes gives no
distance: anywhere else on a face the relief moves the reading by millimetres to centimetres (the
nose reads 25 mm nearer than the eye band, benchmarks/vision.py). The statistic is the interquartile
mean of the region's valid pixels (``scipy.stats.trim_mean``, a quarter cut from each end): it
ignores holes (0) and up to a quarter of stray pixels at either end, as a median would, but where
a median of Kinect v1 depths snaps to one 11-bit disparity level (up to half a step, ~1 mm, off
at 0.83 m), the mean of the middle half averages across levels.

No face, no two eyes, a face at the image's edge, or too few valid depth pixels gives no distance
(NaN) and ``valid = False``, never a number.
"""

import dataclasses
from dataclasses import dataclass

import cv2
import numpy as np
from scipy.stats import trim_mean

from maskless.errors import MasklessError

# (x, y, width, height) in pixels.
Box = tuple[int, int, int, int]

FACE_CASCADE = "haarcascade_frontalface_default.xml"
EYE_CASCADE = "haarcascade_eye.xml"
# OpenCV's usual scale step; 4 neighbours (OpenCV's default is 3) drops the odd false face in the
# background without losing the face itself on rendered frames (tests/test_face_detection.py).
SCALE_FACTOR = 1.1
MIN_NEIGHBORS = 4
# A tracked face is searched for within this fraction of its size around its last box, at sizes
# within this factor of its last size.
TRACKING_MARGIN = 0.3
TRACKING_SIZE_FACTOR = 1.2
# Eyes are searched for in the upper part of the face box, where they are.
EYE_BAND_FRACTION = 0.6
# An eye's box is about a quarter to a third of the face box's width (0.25-0.31 on the portrait and
# on rendered frames); searching only from 0.15 to 0.45 of it skips most of the scale pyramid.
EYE_TYPICAL_FRACTION = 0.28
EYE_SIZE_FRACTION = (0.15, 0.45)
# The eye cascade's own window (pixels): it finds nothing smaller. A face's band is enlarged until
# a typical eye spans _EYE_SEARCH_SIZE_PX, room above the window for an eye smaller than typical.
_EYE_WINDOW_PX = 20
_EYE_SEARCH_SIZE_PX = 26
# A face box closer than this fraction of the image width to an edge may be cut off.
EDGE_MARGIN_FRACTION = 0.01
# The depth region needs at least this fraction of valid pixels.
MIN_VALID_FRACTION = 0.5
# The fraction cut from each end of the region's depths before averaging.
TRIM_FRACTION = 0.25


@dataclass(frozen=True)
class FaceMeasurement:
    """What one image gave.

    Boxes are in the pixels of the image searched (the colour image).

    Attributes:
        face_box: the face, or None.
        eye_boxes: the eyes found within it (0-2), left to right.
        region_box: where the depth was read (the eye band), or None.
        distance_m: the camera-to-face distance (m); NaN when not valid.
        valid: whether ``distance_m`` is a measurement.
        reason: why not, when not valid ("no face", "eyes not found", "face at the image edge",
            "no valid depth", "frame dropped"); empty when valid.
    """

    face_box: Box | None
    eye_boxes: tuple[Box, ...]
    region_box: Box | None
    distance_m: float
    valid: bool
    reason: str = ""


def invalid_measurement(reason: str, face_box: Box | None = None, eye_boxes=()) -> FaceMeasurement:
    """A measurement that is none, saying why."""
    return FaceMeasurement(face_box, tuple(eye_boxes), None, float("nan"), False, reason)


def _cascade(file_name: str):
    if not hasattr(cv2, "CascadeClassifier"):
        raise MasklessError(
            f"OpenCV {cv2.__version__} has no CascadeClassifier (opencv-python-headless 5.0 "
            "dropped it); install opencv-python-headless>=4.12,<5"
        )
    cascade = cv2.CascadeClassifier(cv2.data.haarcascades + file_name)
    if cascade.empty():
        raise MasklessError(f"OpenCV could not load its cascade {file_name}")
    return cascade


class FaceFinder:
    """The face and eye cascades, and how to search with them.

    The eyes of a small face (one found in a downsampled image) are enlarged before the eye
    search, to the size the eye cascade needs; a large face's are searched as they are.
    """

    def __init__(self):
        """Loads OpenCV's stock cascades."""
        self._face = _cascade(FACE_CASCADE)
        self._eye = _cascade(EYE_CASCADE)

    def find_face(self, gray: np.ndarray, last_face: Box | None) -> Box | None:
        """The face in ``gray``, searched for near ``last_face`` first, then everywhere."""
        if last_face is not None:
            found = self._search_near(gray, last_face)
            if found is not None:
                return found
        faces = self._face.detectMultiScale(gray, SCALE_FACTOR, MIN_NEIGHBORS)
        return _largest(faces) if len(faces) else None

    def _search_near(self, gray: np.ndarray, last: Box) -> Box | None:
        x, y, w, h = last
        margin_x, margin_y = int(TRACKING_MARGIN * w), int(TRACKING_MARGIN * h)
        left, top = max(0, x - margin_x), max(0, y - margin_y)
        right = min(gray.shape[1], x + w + margin_x)
        bottom = min(gray.shape[0], y + h + margin_y)
        size = max(w, h)
        faces = self._face.detectMultiScale(
            gray[top:bottom, left:right],
            SCALE_FACTOR,
            MIN_NEIGHBORS,
            minSize=(int(size / TRACKING_SIZE_FACTOR),) * 2,
            maxSize=(int(size * TRACKING_SIZE_FACTOR) + 1,) * 2,
        )
        if not len(faces):
            return None
        fx, fy, fw, fh = _largest(faces)
        return (fx + left, fy + top, fw, fh)

    def find_eyes(self, gray: np.ndarray, face: Box) -> tuple[Box, ...]:
        """Up to two eyes in the upper part of ``face``, left to right, in ``gray``'s pixels."""
        x, y, w, h = face
        band = gray[y : y + int(EYE_BAND_FRACTION * h), x : x + w]
        band_shape = band.shape
        factor = max(1.0, _EYE_SEARCH_SIZE_PX / (EYE_TYPICAL_FRACTION * w))
        if factor != 1.0:
            band = cv2.resize(band, None, fx=factor, fy=factor, interpolation=cv2.INTER_LINEAR)
        smallest, largest = (int(fraction * w * factor) for fraction in EYE_SIZE_FRACTION)
        eyes = self._eye.detectMultiScale(
            band,
            SCALE_FACTOR,
            MIN_NEIGHBORS,
            minSize=(max(smallest, _EYE_WINDOW_PX),) * 2,
            maxSize=(max(largest, _EYE_WINDOW_PX + 1),) * 2,
        )
        largest_two = sorted((tuple(int(v) for v in e) for e in eyes), key=_largest_first)[:2]
        in_band = (scale_box(e, 1.0 / factor, band_shape) for e in largest_two)
        return tuple(sorted((x + ex, y + ey, ew, eh) for ex, ey, ew, eh in in_band))


def _largest(boxes) -> Box:
    """The largest box; ties go to the one nearest the top left.

    OpenCV's multithreaded search returns its boxes in an order that varies from run to run, so
    every choice among them is made by a total order, never by position in the list.
    """
    return min((tuple(int(v) for v in b) for b in boxes), key=_largest_first)


def _largest_first(box: Box) -> tuple:
    x, y, w, h = box
    return (-w * h, y, x)


def scale_box(box, factor: float, shape: tuple[int, ...]) -> Box:
    """``box`` in an image resized by ``factor``, whole pixels, kept within ``shape`` (rows, ...).

    Corners are scaled (not corner and size apart), so a box that touched an edge still does.
    """
    return map_box(box, (factor, factor), shape)


def map_box(box, factors: tuple[float, float], shape: tuple[int, ...]) -> Box:
    """``box`` with x scaled by ``factors[0]`` and y by ``factors[1]``, kept within ``shape``."""
    rows, columns = shape[:2]
    x, y, w, h = (float(v) for v in box)
    left = min(max(round(x * factors[0]), 0), columns)
    top = min(max(round(y * factors[1]), 0), rows)
    right = min(max(round((x + w) * factors[0]), left), columns)
    bottom = min(max(round((y + h) * factors[1]), top), rows)
    return (left, top, right - left, bottom - top)


def depth_region(eyes: tuple[Box, Box]) -> Box:
    """The box the depth is read in: the band spanning both eyes."""
    left = min(e[0] for e in eyes)
    top = min(e[1] for e in eyes)
    right = max(e[0] + e[2] for e in eyes)
    bottom = max(e[1] + e[3] for e in eyes)
    return (left, top, right - left, bottom - top)


def at_image_edge(box: Box, image_shape: tuple[int, ...]) -> bool:
    """Whether ``box`` comes within the edge margin of the image (a face there may be cut off)."""
    rows, columns = image_shape[:2]
    margin = max(2, int(EDGE_MARGIN_FRACTION * columns))
    x, y, w, h = box
    return x < margin or y < margin or x + w > columns - margin or y + h > rows - margin


def region_distance_m(depth_m: np.ndarray) -> float:
    """The interquartile mean of a region's valid (non-zero) depths (m); NaN if too few."""
    values = np.asarray(depth_m).ravel()
    valid = values[values > 0]
    if values.size == 0 or valid.size < MIN_VALID_FRACTION * values.size:
        return float("nan")
    return float(trim_mean(valid.astype(np.float64), TRIM_FRACTION))


def find_face_region(
    finder: FaceFinder, gray: np.ndarray, last_face: Box | None
) -> FaceMeasurement:
    """Finds the face and eyes in ``gray`` and the region to read depth in (no distance yet).

    The result is valid when the region is where a distance should be read; it is invalid, saying
    why, when there is no face, the face is at the image's edge, or its two eyes are not found.
    """
    face = finder.find_face(gray, last_face)
    if face is None:
        return invalid_measurement("no face")
    eyes = finder.find_eyes(gray, face)
    if at_image_edge(face, gray.shape):
        return invalid_measurement("face at the image edge", face, eyes)
    if len(eyes) != 2:
        return invalid_measurement("eyes not found", face, eyes)
    return FaceMeasurement(face, eyes, depth_region(eyes), float("nan"), True)


def with_distance(found: FaceMeasurement, distance_m: float) -> FaceMeasurement:
    """``found`` (from ``find_face_region``) with the distance read in its region."""
    if not found.valid:
        return found
    if not np.isfinite(distance_m):
        return dataclasses.replace(found, valid=False, reason="no valid depth")
    return dataclasses.replace(found, distance_m=float(distance_m))
