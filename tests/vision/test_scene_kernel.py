"""The scene kernel computes what the array version of the renderer did, bit for bit: frames,
and so recorded bags and every figure made from rendered images, do not change with it."""

import hashlib
import math

import numpy as np
import pytest

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.fiducial import (
    CHASSIS_LEVEL,
    CHASSIS_RADIUS_M,
    DOT_LEVEL,
    MACRO_FIDUCIAL,
    MICRO_FIDUCIAL,
    PLATFORM_LEVEL,
)
from omni_micro_vision.rendering import Sensor, _reflectance, pixel_centres, render


def _coverage(distance_m, radius_m, pixel_m):
    return np.clip(0.5 - (distance_m - radius_m) / pixel_m, 0.0, 1.0)


def array_reflectance(xs, ys, pose, pixel_m):
    """The renderer's scene as numpy computed it, one instant at a time (the reference)."""
    x, y, phi = pose
    farthest = math.hypot(max(abs(xs[0] - x), abs(xs[-1] - x)),
                          max(abs(ys[0] - y), abs(ys[-1] - y)))
    if farthest + pixel_m < CHASSIS_RADIUS_M:
        image = np.full((ys.size, xs.size), CHASSIS_LEVEL)
    else:
        image = PLATFORM_LEVEL + (CHASSIS_LEVEL - PLATFORM_LEVEL) * _coverage(
            np.hypot(xs[None, :] - x, ys[:, None] - y), CHASSIS_RADIUS_M, pixel_m)
    cos, sin = math.cos(phi), math.sin(phi)
    for fiducial in (MACRO_FIDUCIAL, MICRO_FIDUCIAL):
        for dot in (fiducial.front, fiducial.back):
            cx = x + cos * dot.x_m - sin * dot.y_m
            cy = y + sin * dot.x_m + cos * dot.y_m
            reach = dot.radius_m + pixel_m
            columns = np.nonzero(np.abs(xs - cx) <= reach)[0]
            rows = np.nonzero(np.abs(ys - cy) <= reach)[0]
            if not columns.size or not rows.size:
                continue
            window = (slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1))
            covered = _coverage(np.hypot(xs[window[1]][None, :] - cx,
                                         ys[window[0]][:, None] - cy), dot.radius_m, pixel_m)
            image[window] += (DOT_LEVEL - image[window]) * covered
    return image


def _window(camera_name, row, column, size=72):
    camera = getattr(DEFAULT_RIG, camera_name)
    xs, ys = pixel_centres(camera)
    px, py = camera.pixel_size_m
    return xs[column:column + size], ys[row:row + size], math.sqrt(px * py)


def _pose_at_pixel(camera_name, row, column):
    camera = getattr(DEFAULT_RIG, camera_name)
    xs, ys = pixel_centres(camera)
    return float(xs[column]), float(ys[row])


@pytest.mark.parametrize('camera, row, column, offset_m, phi, instants, turn_rad', [
    # The macro camera: the chassis's edge and both dot pairs (the micro dots under a pixel,
    # one centred exactly on a pixel centre), still and turning over the exposure.
    ('macro', 500, 600, (0.0, 0.0), 0.3, 1, 0.0),
    ('macro', 500, 600, (0.0042, 0.0011), -1.2, 32, 2e-3),
    ('macro', 500, 600, (0.0021, -0.0003), 2.9, 7, -5e-3),
    # The micro camera: the chassis filling the window, its edge across it, the dots.
    ('micro', 480, 620, (0.0, 0.0), 0.3, 1, 0.0),          # the chassis only: flat
    ('micro', 480, 620, (0.0003, 0.00002), 0.3, 32, 1e-4),
    ('micro', 480, 620, (0.0045, 0.0001), 0.1, 32, -2e-4),
    ('micro', 100, 1200, (-0.00451, 0.0), 1.0, 3, 0.0),
])
def test_the_kernel_sums_exactly_what_the_array_version_drew_per_instant(
        camera, row, column, offset_m, phi, instants, turn_rad):
    xs, ys, pixel_m = _window(camera, row, column)
    centre_x, centre_y = _pose_at_pixel(camera, row + 36, column + 36)
    poses = [(centre_x - offset_m[0] + 1e-6 * k, centre_y - offset_m[1] - 4e-7 * k,
              phi + turn_rad * k / max(instants - 1, 1)) for k in range(instants)]
    reference = sum(array_reflectance(xs, ys, pose, pixel_m) for pose in poses)
    assert np.array_equal(_reflectance(xs, ys, poses, pixel_m), reference)
    # Each case draws what it says: an outline, or the chassis filling the window.
    if offset_m == (0.0, 0.0) and camera == 'micro':
        assert np.all(reference == CHASSIS_LEVEL)
    else:
        assert np.ptp(reference) > 0.05 * instants


# SHA-256 (first 16 hex digits) of frames drawn by the array version of the renderer: the
# same seed must still give these frames. (camera, state, yaw, 8-bit digest, 16-bit digest)
FRAMES = [
    ('macro', RobotState(0.05, 0.01, 0.3, 0.0, 0.0, 0.0), 0.0,
     '4b3959764f0b4ee6', '4cf7e9a1e2f0fcc1'),
    ('macro', RobotState(0.05, 0.01, 0.3, 0.012, -0.004, 0.05), 0.02,
     'cf162e4bbfda1f5a', '213cfed4db99fbfe'),
    ('micro', RobotState(0.1, 0.0, 0.3, 0.0, 0.0, 0.0), 0.0,
     'af3a836623c17293', '47ba9e42d5895b1b'),
    ('micro', RobotState(0.1003, 0.0002, -0.4, 0.011, 0.003, -0.04), 0.0,
     '393fd82c3f7a2207', '6250b1365be49e81'),
    ('micro', RobotState(0.0960, 0.0004, 0.1, 0.009, 0.0, -0.03), 0.0,
     '531b1cd034662127', '6eca9a597ebb7c93'),
]


@pytest.mark.parametrize('camera, state, yaw, digest8, digest16', FRAMES)
def test_frames_are_the_ones_the_array_version_drew(camera, state, yaw, digest8, digest16):
    for bits, digest in ((8, digest8), (16, digest16)):
        frame = render(getattr(DEFAULT_RIG, camera), Sensor(bit_depth=bits), state,
                       np.random.default_rng([7, bits]), yaw)
        assert hashlib.sha256(frame.tobytes()).hexdigest()[:16] == digest, (camera, bits)


def test_a_dot_smaller_than_a_pixel_centred_on_one_covers_part_of_it():
    """The macro camera's 117 um pixel under the 70 um micro back dot: not covered whole."""
    xs, ys, pixel_m = _window('macro', 500, 600)
    dot = MICRO_FIDUCIAL.back
    # A robot heading along x whose back micro dot lands exactly on a pixel centre.
    column = next(c for c in range(20, 50) if (float(xs[c]) - dot.x_m) + dot.x_m == xs[c])
    pose = (float(xs[column]) - dot.x_m, float(ys[36]), 0.0)
    image = _reflectance(xs, ys, [pose], pixel_m)
    assert np.array_equal(image, array_reflectance(xs, ys, pose, pixel_m))
    assert CHASSIS_LEVEL < image[36, column] < DOT_LEVEL
