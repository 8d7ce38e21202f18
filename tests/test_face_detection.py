"""Finding the face and eyes with OpenCV's cascades, and reading a robust depth in the eye band."""

import cv2
import numpy as np
import pytest
from scipy import stats

from maskless.systems.config_loading import asset_path
from maskless.systems.sensing.face_detection import (
    FaceFinder,
    at_image_edge,
    depth_region,
    find_face_region,
    map_box,
    region_distance_m,
    scale_box,
    with_distance,
)


@pytest.fixture(scope="module")
def finder():
    return FaceFinder()


@pytest.fixture(scope="module")
def portrait():
    """The face texture, grey, on a larger grey background (the face well inside the image)."""
    face = cv2.cvtColor(cv2.imread(str(asset_path("face/face.png"))), cv2.COLOR_BGR2GRAY)
    image = np.full((480, 640), 110, np.uint8)
    image[100 : 100 + face.shape[0], 200 : 200 + face.shape[1]] = face
    return image


def test_the_cascades_find_the_face_and_both_eyes_in_the_portrait(finder, portrait):
    found = find_face_region(finder, portrait, None)
    assert found.valid
    x, y, w, h = found.face_box
    assert 200 <= x and x + w <= 400 and 100 <= y and y + h <= 340  # on the texture
    assert len(found.eye_boxes) == 2
    left, right = found.eye_boxes
    assert left[0] < right[0]  # left to right
    for ex, ey, ew, eh in found.eye_boxes:  # eyes in the face's upper part
        assert x <= ex and ex + ew <= x + w and y <= ey and ey + eh <= y + 0.6 * h + 1
    assert found.region_box == depth_region(found.eye_boxes)


def test_a_tracked_face_is_found_near_its_last_box_and_a_lost_one_everywhere(finder, portrait):
    first = finder.find_face(portrait, None)
    # The near search scans other scales, so its box differs by a few pixels: same face.
    assert _overlap(finder.find_face(portrait, first), first) > 0.8
    # A stale box far from the face: the near search fails and the full search finds it.
    assert finder.find_face(portrait, (10, 10, 40, 40)) == first


def _overlap(a, b):
    """Intersection over union of two boxes."""
    width = min(a[0] + a[2], b[0] + b[2]) - max(a[0], b[0])
    height = min(a[1] + a[3], b[1] + b[3]) - max(a[1], b[1])
    inter = max(0, width) * max(0, height)
    return inter / (a[2] * a[3] + b[2] * b[3] - inter)


def test_a_blank_image_has_no_face_and_no_distance(finder):
    found = find_face_region(finder, np.full((240, 320), 128, np.uint8), None)
    assert not found.valid and found.reason == "no face"
    assert with_distance(found, 0.8) == found  # nothing turns it into a number


def test_a_face_cut_by_the_image_edge_gives_no_distance(finder, portrait):
    x, y, w, h = finder.find_face(portrait, None)
    # Cut the image through the face's right eye.
    cropped = np.ascontiguousarray(portrait[:, : x + 3 * w // 4])
    found = find_face_region(finder, cropped, None)
    assert not found.valid
    assert found.reason in ("face at the image edge", "no face")


class _FaceAtTheEdge:
    """A finder that reports a face touching the image's left edge, with both eyes."""

    def find_face(self, gray, last_face):
        return (1, 50, 60, 60)

    def find_eyes(self, gray, face):
        return ((10, 60, 12, 12), (35, 60, 12, 12))


def test_a_face_box_at_the_image_edge_gives_no_distance():
    found = find_face_region(_FaceAtTheEdge(), np.zeros((240, 320), np.uint8), None)
    assert not found.valid and found.reason == "face at the image edge"
    assert found.face_box == (1, 50, 60, 60)  # kept for the tracker


def test_edge_margin():
    assert at_image_edge((0, 50, 20, 20), (240, 320))
    assert at_image_edge((300, 50, 19, 20), (240, 320))
    assert not at_image_edge((100, 100, 40, 40), (240, 320))


def test_depth_region_is_the_band_spanning_both_eyes():
    eyes = ((10, 20, 8, 6), (30, 22, 10, 8))
    assert depth_region(eyes) == (10, 20, 30, 10)


def test_a_face_without_both_eyes_gives_no_distance(finder, portrait):
    face = finder.find_face(portrait, None)
    x, y, w, h = face
    masked = portrait.copy()
    masked[y : y + h // 2, x + w // 2 : x + w] = 110  # paint out the right eye (and brow)
    found = find_face_region(finder, masked, face)
    assert len(found.eye_boxes) < 2
    assert not found.valid and found.reason == "eyes not found"
    assert found.face_box is not None  # kept, so the tracker keeps the face


def test_region_distance_is_scipys_interquartile_mean_of_valid_pixels():
    rng = np.random.default_rng(0)
    depth = rng.normal(0.8, 0.002, (20, 30))
    depth[:4] = 0.0  # holes are ignored
    depth[5, :10] = 3.0  # stray pixels (background) are trimmed
    valid = depth[depth > 0]
    assert region_distance_m(depth) == pytest.approx(stats.trim_mean(valid, 0.25))
    assert region_distance_m(depth) == pytest.approx(0.8, abs=5e-4)


def test_a_region_mostly_holes_gives_no_distance():
    depth = np.zeros((10, 10))
    depth[0, : 40 // 10] = 0.8
    assert np.isnan(region_distance_m(depth))
    assert np.isnan(region_distance_m(np.zeros((0, 0))))


def test_a_found_region_without_valid_depth_is_invalid(finder, portrait):
    found = find_face_region(finder, portrait, None)
    measured = with_distance(found, float("nan"))
    assert not measured.valid and measured.reason == "no valid depth"
    assert with_distance(found, 0.81).distance_m == 0.81


def test_scale_box_scales_corners_and_stays_in_the_image():
    assert scale_box((10, 11, 20, 21), 2.0, (480, 640)) == (20, 22, 40, 42)
    # Corners, not corner and size: (3, 3)-(8, 8) halves to (2, 2)-(4, 4).
    assert scale_box((3, 3, 5, 5), 0.5, (480, 640)) == (2, 2, 2, 2)
    # A box reaching past the image is cut at its edge.
    assert scale_box((300, 230, 30, 20), 2.0, (480, 640)) == (600, 460, 40, 20)
    assert map_box((10, 10, 10, 10), (2.0, 3.0), (480, 640)) == (20, 30, 20, 30)
