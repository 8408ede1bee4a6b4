"""Camera model: pixel-derived noise, quantisation, fields, and the stationary-capture rule."""

import math
from typing import Any

import numpy as np
import pytest

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_vision.camera import (
    DEFAULT_RIG,
    CameraModel,
    Capture,
    CaptureRule,
    OutOfField,
    StationaryCamera,
    capture_rng,
)
from omni_micro_vision.errors import CameraConfigError


def test_pixel_size_is_field_over_resolution():
    assert DEFAULT_RIG.macro.pixel_size_m == pytest.approx((0.15 / 1280, 0.15 / 1024))
    assert DEFAULT_RIG.micro.pixel_size_m == pytest.approx((0.002 / 1280, 0.002 / 1024))


def test_noise_scales_with_the_pixel_and_is_quantised():
    errors = {}
    for camera in (DEFAULT_RIG.macro, DEFAULT_RIG.micro):
        x0 = camera.center_m[0] + 1.234e-4
        measured = np.array([camera.measure(x0, 0.0, 0.0, capture_rng(1, 0, k))
                             for k in range(2000)])
        errors[camera.name] = np.std(measured[:, 0] - x0)
        grid = camera.pixel_size_m[0] * camera.quantisation_px
        origin = camera.center_m[0] - camera.field_m[0] / 2
        # Each mark lies on the sub-pixel grid, so the midpoint lies on the half grid.
        offsets = (measured[:, 0] - origin) / (grid / 2)
        assert np.allclose(offsets, np.round(offsets), atol=1e-6)
        # Two marks averaged: sigma / sqrt(2), plus a little quantisation.
        expected = camera.noise_px * camera.pixel_size_m[0] / math.sqrt(2)
        assert errors[camera.name] == pytest.approx(expected, rel=0.15)
    assert errors['macro'] / errors['micro'] == pytest.approx(75.0, rel=0.2)


def test_noise_depends_only_on_seed_stop_and_frame():
    camera = DEFAULT_RIG.macro
    first = camera.measure(0.01, 0.0, 0.1, capture_rng(7, 3, 2))
    assert camera.measure(0.01, 0.0, 0.1, capture_rng(7, 3, 2)) == first
    assert camera.measure(0.01, 0.0, 0.1, capture_rng(7, 3, 1)) != first
    assert camera.measure(0.01, 0.0, 0.1, capture_rng(8, 3, 2)) != first


def test_micro_camera_inside_its_field_none_outside_the_macro_field():
    assert DEFAULT_RIG.camera_for(0.1, 0.0005) is DEFAULT_RIG.micro
    assert DEFAULT_RIG.camera_for(0.098, 0.0) is DEFAULT_RIG.macro
    assert DEFAULT_RIG.camera_for(0.2, 0.0) is None


def feed(camera: StationaryCamera, stamps, speed=0.0, x=0.05):
    events = []
    for stamp in stamps:
        events += camera.on_odometry(stamp, x, 0.0, 0.0, speed, 0.0)
    return events


def test_captures_only_after_dwell_at_frame_rate_and_never_while_moving():
    rule = CaptureRule(dwell_s=0.02, frame_rate_hz=30.0)
    camera = StationaryCamera(rule=rule, seed=0)
    assert feed(camera, [0.02, 0.04], speed=1e-3) == []
    events = feed(camera, np.arange(0.06, 0.30, 0.02))
    stamps = [e.stamp_s for e in events]
    assert stamps[0] == pytest.approx(0.06 + 0.02)
    assert np.diff(stamps) == pytest.approx(1 / 30.0)
    assert all(isinstance(e, Capture) and e.stop_index == 0 for e in events)
    assert [e.frame_index for e in events] == list(range(len(events)))
    # Motion ends the stop; the next stop has index 1 and counts frames from 0 again.
    assert feed(camera, [0.32], speed=1e-3) == []
    again = feed(camera, np.arange(0.34, 0.44, 0.02))
    assert again[0].stop_index == 1 and again[0].frame_index == 0


def test_outside_every_field_gives_an_event_not_a_capture():
    events = feed(StationaryCamera(seed=0), np.arange(0.02, 0.2, 0.02), x=0.3)
    assert events and all(isinstance(e, OutOfField) for e in events)


def test_repeated_samples_add_nothing():
    camera = StationaryCamera(seed=0)
    first = feed(camera, np.arange(0.02, 0.2, 0.02))
    assert feed(camera, [0.1, 0.12]) == []
    assert first


@pytest.mark.parametrize('kwargs, name', [
    ({'field_m': (0.0, 0.1)}, 'field_m'), ({'resolution_px': (1280.5, 1024)}, 'resolution_px'),
    ({'noise_px': -1.0}, 'noise_px'), ({'center_m': (math.nan, 0.0)}, 'center_m')])
def test_bad_camera_parameters_name_the_value(kwargs, name):
    base: dict[str, Any] = dict(name='macro', center_m=(0.0, 0.0), field_m=(0.15, 0.15))
    base.update(kwargs)
    with pytest.raises(CameraConfigError, match=name):
        CameraModel(**base)


def test_bad_rule_and_seed_name_the_value():
    with pytest.raises(CameraConfigError, match='frame_rate_hz'):
        CaptureRule(frame_rate_hz=0.0)
    with pytest.raises(CameraConfigError, match='seed'):
        StationaryCamera(seed=-1)


@pytest.mark.parametrize('camera', [DEFAULT_RIG.macro, DEFAULT_RIG.micro], ids=['macro', 'micro'])
@pytest.mark.parametrize('heading', [0.0, 0.7, 2.0])
def test_the_stated_uncertainty_is_the_spread_of_the_captures(camera, heading):
    x0, y0 = camera.center_m[0] + 3.3e-5, camera.center_m[1] - 2.1e-5
    samples = np.array([camera.measure(x0, y0, heading, capture_rng(5, 0, k))
                        for k in range(4000)])
    stated = camera.uncertainty(heading)
    measured = (np.std(samples[:, 0]), np.std(samples[:, 1]),
                np.std(np.remainder(samples[:, 2] - heading + math.pi, 2 * math.pi) - math.pi))
    # 4000 draws pin a standard deviation to about 2 %; the model must be within 10 %.
    assert measured == pytest.approx((stated.x_sigma_m, stated.y_sigma_m,
                                      stated.heading_sigma_rad), rel=0.1)
    distances = np.hypot(samples[:, 0] - x0, samples[:, 1] - y0)
    inside = np.mean(distances <= stated.radius_95_m)
    assert 0.94 <= inside <= 0.995   # the larger axis is used, so at least 95 %


def test_each_capture_carries_its_uncertainty_through_a_covariance():
    camera = StationaryCamera(seed=3)
    events = camera.on_odometry(1.0, 0.1, 0.0, 0.3, 0.0, 0.0) + \
        camera.on_odometry(1.05, 0.1, 0.0, 0.3, 0.0, 0.0)
    capture = next(event for event in events if isinstance(event, Capture))
    assert capture.uncertainty == DEFAULT_RIG.micro.uncertainty(capture.phi_rad)
    matrix = capture.uncertainty.covariance()
    assert len(matrix) == 36 and matrix[0] > 0 and matrix[7] > 0 and matrix[35] > 0
    back = CaptureUncertainty.from_covariance(matrix)
    assert back.x_sigma_m == pytest.approx(capture.uncertainty.x_sigma_m, rel=1e-15)
    assert back.radius_95_m < 0.4e-6 < DEFAULT_RIG.macro.uncertainty(0.0).radius_95_m


@pytest.mark.parametrize('matrix, message', [
    ([0.0] * 35, '36 values'),
    ([-1.0] + [0.0] * 35, 'x variance'),
    ([0.0] * 35 + [math.nan], 'yaw variance'),
])
def test_a_broken_covariance_is_refused_naming_the_problem(matrix, message):
    with pytest.raises(ValueError, match=message):
        CaptureUncertainty.from_covariance(matrix)


@pytest.mark.parametrize('resolution', [[100000, 100000], [20000, 10], [6000, 5000]])
def test_a_frame_larger_than_a_camera_is_refused_before_any_memory_is_taken(resolution):
    """camera_node -p 'macro.resolution_px:=[100000,100000]' asked 74.5 GiB of a MemoryError."""
    with pytest.raises(CameraConfigError, match=r'macro.resolution_px \[\d+, \d+\] is larger '
                                                r'than a camera: at most 16384 a side and 25 '
                                                r'megapixels'):
        CameraModel('macro', (0.05, 0.0), (0.15, 0.15), resolution)
    CameraModel('macro', (0.05, 0.0), (0.15, 0.15), (5472, 3648))   # a 20-megapixel sensor
