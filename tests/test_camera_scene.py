"""The rendered scene: the head follows its height port, and depth under the face is exact."""

import numpy as np
import pytest
from rendered_scene import build_rendered_scene, head_travel_m, shipped_cameras

from maskless.systems.sensing.camera_scene import camera_pose


@pytest.fixture(scope="module")
def scene():
    return build_rendered_scene(shipped_cameras())


@pytest.mark.parametrize("height_m", head_travel_m())
@pytest.mark.parametrize("name", ["kinect_v1", "kinect_v2"])
def test_depth_at_the_face_centre_is_mount_height_minus_head_height(scene, name, height_m):
    config, _ = scene.cameras[name]
    _, depth = scene.render(name, height_m)
    rows, columns = depth.shape
    focal_x = columns / 2 / np.tan(np.radians(config.rendering.horizontal_fov_deg) / 2)
    distance = config.mount_height_m - height_m
    # The face's centre (table x = y = 0) seen from a camera at position_m, looking down.
    column = (columns - 1) / 2 + focal_x * (0.0 - config.rendering.position_m[0]) / distance
    row = (rows - 1) / 2  # y offset 0: image rows run along -y
    value = depth[int(round(row)), int(round(column))]
    assert value == pytest.approx(distance, abs=1e-6)


def test_the_image_has_the_camera_resolution_and_colour_the_scaled_one(scene):
    for name, (config, _) in scene.cameras.items():
        rgb, depth = scene.render(name, 0.21)
        rendering = config.rendering
        assert depth.shape == (rendering.image_height_px, rendering.image_width_px)
        assert rgb.shape[:2] == (
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
