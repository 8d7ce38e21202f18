"""The camera-frames plot: a whole PNG a row per camera (Pillow), its boxes in their colours."""

from pathlib import Path

import numpy as np
import pytest
from camera_frames import empty_frame, face_frame
from PIL import Image
from png_images import assert_png

from maskless.analysis.camera_frames_plot import plot_camera_frames

# 10 inches wide at 100 dpi; 3.6 inches a camera.
WIDTH_PX, ROW_PX = 1000, 360


def _pixels_near(path, rgb, tolerance=40):
    """How many pixels of the PNG lie within ``tolerance`` of the colour ``rgb`` (0-255)."""
    with Image.open(path) as image:
        pixels = np.asarray(image.convert("RGB")).astype(int)
    return int((np.abs(pixels - np.array(rgb)).max(axis=-1) < tolerance).sum())


def test_one_camera_is_one_row_of_its_first_and_last_frame(tmp_path):
    path = tmp_path / "frames.png"
    frames = {"kinect_v1": [face_frame(time_s=0.1), face_frame(time_s=0.2), empty_frame()]}
    written = plot_camera_frames(str(path), frames)
    assert written == path and isinstance(written, Path)
    assert_png(path, WIDTH_PX, ROW_PX)
    # The face boxes are drawn in green (which the gradient image lacks); beyond the legend's.
    no_face = plot_camera_frames(tmp_path / "no_face.png", {"kinect_v1": [empty_frame()]})
    green = (0, 204, 0)
    assert _pixels_near(path, green) > _pixels_near(no_face, green) + 200


def test_each_camera_adds_a_row(tmp_path):
    frames = {
        "kinect_v1": [face_frame("kinect_v1")],
        "kinect_v2": [empty_frame("kinect_v2"), face_frame("kinect_v2", time_s=0.7)],
        "zed_2": [empty_frame("zed_2")],
    }
    path = plot_camera_frames(tmp_path / "frames.png", frames)
    assert_png(path, WIDTH_PX, 3 * ROW_PX)


def test_a_camera_without_frames_is_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match="camera 'kinect_v2': no frames"):
        plot_camera_frames(tmp_path / "frames.png", {"kinect_v1": [face_frame()], "kinect_v2": []})
    with pytest.raises(ValueError, match="no camera"):
        plot_camera_frames(tmp_path / "frames.png", {})
    assert not (tmp_path / "frames.png").exists()
