"""A rendered depth image made Kinect-like: published per-pixel noise, quantisation and holes."""

import numpy as np
import pytest
from rendered_scene import shipped_cameras

from maskless.systems.sensing.depth_image_noise import kinect_depth_image

PIXELS = (400, 500)


@pytest.fixture
def cameras():
    return shipped_cameras(invalid_pixel_probability=0.0)


def test_noise_free_kinect_v1_reports_an_11_bit_disparity_level(cameras):
    depth = kinect_depth_image(np.full((3, 3), 0.83), cameras["kinect_v1"], 0.0, None)
    # z = 1 / (-0.00307 d + 3.3309) with d a whole disparity (shared/DESIGN.md).
    disparity = (1.0 / depth.astype(np.float64) - 3.3309) / -0.00307
    np.testing.assert_allclose(disparity, np.round(disparity), atol=1e-3)
    step_m = 0.00307 * 0.83**2
    assert np.all(np.abs(depth - 0.83) <= step_m / 2 + 1e-6)


def test_kinect_v1_pixel_noise_is_nguyen_et_al(cameras):
    z = 0.83
    depth = kinect_depth_image(
        np.full(PIXELS, z), cameras["kinect_v1"], 0.0, np.random.default_rng(1)
    )
    # sigma = 1.2 mm + 1.9 mm (z - 0.4)^2 (Nguyen, Izadi, Lovell 2012), plus the quantisation's
    # step^2 / 12 of a uniform rounding error.
    sigma = 0.0012 + 0.0019 * (z - 0.4) ** 2
    step = 0.00307 * z**2
    assert depth.std() == pytest.approx(np.sqrt(sigma**2 + step**2 / 12), rel=0.03)
    assert depth.mean() == pytest.approx(z, abs=2e-4)


def test_kinect_v2_pixel_noise_is_fankhauser_et_al_with_offset_and_drift(cameras):
    z = 0.69
    camera = cameras["kinect_v2"]
    camera.offset_m = 0.002
    depth = kinect_depth_image(np.full(PIXELS, z), camera, 0.0, np.random.default_rng(2))
    sigma = (1.5 - 0.5 * z + 0.3 * z**2) * 1e-3  # Fankhauser et al. 2015, mm -> m
    step = camera.resolution_m
    assert depth.std() == pytest.approx(np.sqrt(sigma**2 + step**2 / 12), rel=0.03)
    drift = camera.warmup_drift_m * np.exp(-camera.warmup_elapsed_s / camera.warmup_time_constant_s)
    assert depth.mean() == pytest.approx(z + 0.002 + drift, abs=1e-4)
    np.testing.assert_allclose(depth / step, np.round(depth / step), atol=1e-3)  # whole mm


@pytest.mark.parametrize("value", [0.0, np.inf, 0.3, 6.0])
def test_pixels_with_nothing_in_range_read_zero(cameras, value):
    for camera in cameras.values():
        depth = kinect_depth_image(np.full((4, 4), value), camera, 0.0, np.random.default_rng(0))
        assert np.all(depth == 0.0)


def test_lost_pixels_read_zero_at_the_configured_rate(cameras):
    camera = cameras["kinect_v2"]
    camera.rendering.invalid_pixel_probability = 0.05
    depth = kinect_depth_image(np.full(PIXELS, 0.7), camera, 0.0, np.random.default_rng(3))
    n = depth.size
    # Binomial: within 5 standard deviations of n p.
    assert abs(np.count_nonzero(depth == 0) - 0.05 * n) < 5 * np.sqrt(n * 0.05 * 0.95)


def test_the_same_generator_seed_gives_the_same_image(cameras):
    camera = cameras["kinect_v1"]
    first = kinect_depth_image(np.full((50, 60), 0.8), camera, 1.0, np.random.default_rng(7))
    again = kinect_depth_image(np.full((50, 60), 0.8), camera, 1.0, np.random.default_rng(7))
    assert first.dtype == np.float32
    np.testing.assert_array_equal(first, again)
