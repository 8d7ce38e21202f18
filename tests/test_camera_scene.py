"""The rendered scene: the head follows its height port, and depth under the face is exact."""

import numpy as np
import pytest
from rendered_scene import build_rendered_scene, head_travel_m, shipped_cameras

from maskless.systems.sensing.camera_scene import camera_pose


@pytest.fixture(scope="module")
def scene():
    return build_rendered_scene(shipped_cameras())


@pytest.mark.parametrize("name", ["kinect_v1", "kinect_v2"])
def test_the_face_moves_with_the_head_height_port(scene, name):
    lowest, _, highest = head_travel_m()
    _, low = scene.render(name, lowest)
    _, high = scene.render(name, highest)
    # The principal point's ray is vertical, so it meets the same point of the face at any height:
    # its depth shrinks by exactly the rise.
    row, column = (size // 2 for size in low.shape)
    assert low[row, column] - high[row, column] == pytest.approx(highest - lowest, abs=1e-6)
    # Elsewhere on the face the camera sees less of the table (the head is nearer), never more.
    on_face = np.isfinite(low) & (low < scene.cameras[name][0].mount_height_m - 0.05)
    assert np.all(high[on_face] < low[on_face])


def test_the_image_has_the_camera_resolution_and_colour_the_scaled_one(scene):
    for name, (config, _) in scene.cameras.items():
        rgba, depth = scene.render(name, 0.21)
        rendering = config.rendering
        assert depth.shape == (rendering.image_height_px, rendering.image_width_px)
        assert rgba.shape[:2] == (
            round(rendering.image_height_px * rendering.color_scale),
            round(rendering.image_width_px * rendering.color_scale),
        )


def test_past_the_table_there_is_nothing_to_measure(scene):
    # The v2's wide view sees past the table's end: nothing within the clipping range, inf.
    _, depth = scene.render("kinect_v2", 0.21)
    assert np.isinf(depth[0, 0])


def test_camera_pose_looks_down_with_image_down_along_minus_y():
    pose = camera_pose([0.1, -0.2], 0.9)
    rotation = pose.rotation().matrix()
    np.testing.assert_allclose(rotation[:, 2], [0, 0, -1])  # optical axis down
    np.testing.assert_allclose(rotation[:, 1], [0, -1, 0])  # image down = towards the chin
    np.testing.assert_allclose(pose.translation(), [0.1, -0.2, 0.9])
