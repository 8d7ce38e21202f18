"""A rendered depth image made to read like a Kinect's: per-pixel noise, quantisation, holes.

Drake renders exact depth. Each pixel then gets the same warm-up drift, published axial noise and
quantisation the measurement model applies to its one distance (``depth_sensor``: Kinect v1 after
Nguyen, Izadi, Lovell 2012 with 11-bit disparity levels; Kinect v2 after Fankhauser et al. 2015, in
whole-millimetre steps), so the two fidelities share one formula. Pixels outside the working range,
rendered too near or too far, or lost at random (``rendering.invalid_pixel_probability``) read 0, as
a Kinect reports a pixel it could not measure.
"""

import numpy as np

from maskless.systems.sensing.depth_sensor import DepthSensorConfig, reported_distance_m


def kinect_depth_image(
    depth_m: np.ndarray,
    config: DepthSensorConfig,
    time_s: float,
    rng: np.random.Generator | None,
) -> np.ndarray:
    """The depth image a camera reports for an exact rendered one.

    Args:
        depth_m: exact depth along the optical axis per pixel (m), shape (rows, columns); Drake's
            values for nothing in range (0 too near, inf too far) are allowed.
        config: the camera (its model, working range, noise terms and
            ``rendering.invalid_pixel_probability``).
        time_s: the frame's simulated time (s), for the warm-up drift.
        rng: draws the noise and the lost pixels; None for the noise-free image (still quantised
            and range-limited, so it is the image of a perfect camera of this model).

    Returns:
        float32 depth (m) per pixel, 0 where the camera reports no measurement.
    """
    depth = np.asarray(depth_m, dtype=np.float64)
    in_range = np.isfinite(depth) & (depth >= config.min_range_m) & (depth <= config.max_range_m)
    exact = np.where(in_range, depth, 1.0)  # any in-range value; masked out below
    noise = (
        rng.standard_normal(depth.shape, dtype=np.float32).astype(np.float64)
        if rng is not None
        else 0.0
    )
    reported = reported_distance_m(config, exact, noise, time_s)
    valid = in_range
    probability = config.rendering.invalid_pixel_probability
    if rng is not None and probability > 0:
        valid = valid & (rng.random(depth.shape, dtype=np.float32) >= probability)
    return np.where(valid, reported, 0.0).astype(np.float32)
