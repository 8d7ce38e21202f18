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


def test_kinect_v2_pixel_noise_is_fankhauser_et_al_with_drift(cameras):
    z = 0.69
    camera = cameras["kinect_v2"]
    camera.warmup_elapsed_s = 0.0  # the whole 3 mm drift
    depth = kinect_depth_image(np.full(PIXELS, z), camera, 0.0, np.random.default_rng(2))
    sigma = (1.5 - 0.5 * z + 0.3 * z**2) * 1e-3  # Fankhauser et al. 2015, mm -> m
    step = camera.resolution_m
    assert depth.std() == pytest.approx(np.sqrt(sigma**2 + step**2 / 12), rel=0.03)
    assert depth.mean() == pytest.approx(z + camera.warmup_drift_m, abs=1e-4)
    np.testing.assert_allclose(depth / step, np.round(depth / step), atol=1e-3)  # whole mm


@pytest.mark.parametrize("name", ["kinect_v1", "kinect_v2"])
def test_noise_free_image_carries_the_decaying_warmup_drift(cameras, name):
    camera = cameras[name]
    camera.warmup_drift_m, camera.warmup_time_constant_s, camera.warmup_elapsed_s = 0.01, 20.0, 5.0
    z = 0.83
    for time_s in (0.0, 7.0, 20.0, 45.0):
        depth = kinect_depth_image(np.full((3, 3), z), camera, time_s, None)
        # drift(t) = drift0 exp(-(t + elapsed) / time constant), added before quantisation.
        drifted = z + 0.01 * np.exp(-(time_s + 5.0) / 20.0)
        if name == "kinect_v1":  # the nearest 11-bit disparity level
            expected = 1 / (-0.00307 * np.round((1 / drifted - 3.3309) / -0.00307) + 3.3309)
        else:  # whole millimetres
            expected = 0.001 * np.round(drifted / 0.001)
        np.testing.assert_allclose(depth, np.float32(expected), rtol=0, atol=1e-7)


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
