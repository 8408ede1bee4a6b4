"""Captures of a moving robot (omni_micro_vision.motion_capture): stamped at mid-exposure, their
spread grown along the travel only, checked against the tracker on rendered frames per speed,
and the speed beyond which the tracker loses the robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import PlaneMap
from omni_micro_vision.motion_capture import (
    CameraTiming,
    MotionCapture,
    MovingCamera,
    along_travel_factor,
    blur_m,
    capture_age_bound_s,
    dot_radius_m,
    max_trackable_speed_m_s,
    measure_in_motion,
    trackable,
    uncertainty_in_motion,
)
from omni_micro_vision.rendering import Sensor, render
from omni_micro_vision.tracking import track

SENSOR = Sensor()
EXPOSURE_S = SENSOR.exposure_s
# The robot's cruise: 8.7 rad/s on 1.65 mm wheels.
CRUISE_M_S = 8.7 * 1.65e-3
HEADING = 0.3   # of the travel, against the platform's x
FRAMES = 24


def tracked_errors(camera: CameraModel, speed_m_s: float) -> tuple[np.ndarray, int]:
    """The tracker's error against the mid-exposure pose, (along, across) the travel, over
    FRAMES rendered frames of the robot moving at ``speed_m_s``; and how many it lost."""
    plane = PlaneMap.nominal(camera)
    rng = np.random.default_rng(5)
    cos, sin = math.cos(HEADING), math.sin(HEADING)
    errors, lost = [], 0
    for frame in range(FRAMES):
        x = camera.center_m[0] + rng.uniform(-0.2, 0.2) * camera.field_m[0]
        y = camera.center_m[1] + rng.uniform(-0.2, 0.2) * camera.field_m[1]
        phi = rng.uniform(-math.pi, math.pi)
        vx, vy = speed_m_s * cos, speed_m_s * sin
        found = track(render(camera, SENSOR, RobotState(x, y, phi, vx, vy, 0.0),
                             np.random.default_rng([7, frame])), plane)
        if found.pose is None:
            lost += 1
            continue
        dx = found.pose[0] - (x + 0.5 * EXPOSURE_S * vx)
        dy = found.pose[1] - (y + 0.5 * EXPOSURE_S * vy)
        errors.append((dx * cos + dy * sin, -dx * sin + dy * cos))
    return np.array(errors), lost


def along(uncertainty, heading: float) -> float:
    return math.hypot(uncertainty.x_sigma_m * math.cos(heading),
                      uncertainty.y_sigma_m * math.sin(heading))


@pytest.mark.parametrize(('camera', 'speeds'), [
    (DEFAULT_RIG.macro, (0.0, CRUISE_M_S, 0.16)),
    (DEFAULT_RIG.micro, (0.0, 0.002, CRUISE_M_S * 0.8)),
], ids=['macro', 'micro'])
def test_rendered_frames_in_motion_are_unbiased_at_mid_exposure_and_within_the_stated_spread(
        camera, speeds):
    """Per speed: the tracker finds every frame, its error about the mid-exposure pose has no
    bias beyond its sampling error (a stamp at the exposure's start would be v * exposure / 2
    off: 29 um at cruise), and its spread along the travel is within what the model states."""
    for speed in speeds:
        assert trackable(camera, speed, EXPOSURE_S)
        errors, lost = tracked_errors(camera, speed)
        assert lost == 0, (camera.name, speed)
        spread = errors.std(axis=0)
        bias = errors.mean(axis=0)
        assert np.all(np.abs(bias) <= 4.0 * spread / math.sqrt(len(errors))), (speed, bias)
        stated = uncertainty_in_motion(camera, 0.0, speed * math.cos(HEADING),
                                       speed * math.sin(HEADING), EXPOSURE_S)
        assert spread[0] <= along(stated, HEADING), (camera.name, speed, spread, stated)
        assert 0.5 * EXPOSURE_S * speed == 0.0 or 0.5 * EXPOSURE_S * speed > 10 * spread[0]


@pytest.mark.parametrize('camera', [DEFAULT_RIG.macro, DEFAULT_RIG.micro],
                         ids=['macro', 'micro'])
def test_beyond_the_stated_speed_the_tracker_loses_the_robot_or_its_precision(camera):
    still, _ = tracked_errors(camera, 0.0)
    limit = max_trackable_speed_m_s(camera, EXPOSURE_S)
    assert trackable(camera, 0.99 * limit, EXPOSURE_S)
    assert not trackable(camera, 1.01 * limit, EXPOSURE_S)
    # Twice the stated limit: frames lost, or the spread several times the still one.
    errors, lost = tracked_errors(camera, 2.5 * limit)
    assert lost > 0 or errors.std(axis=0)[0] > 3 * still.std(axis=0)[0], (lost, errors.std(0))


def test_the_micro_camera_cannot_follow_the_robot_at_cruise():
    """The macro camera follows the robot at any speed it has; the micro camera's smaller dot
    (35 um) is smeared over 1.64 radii at cruise (57 um in 4 ms): the final approach must be
    slower than 12.25 mm/s, or the exposure shorter."""
    assert max_trackable_speed_m_s(DEFAULT_RIG.macro, EXPOSURE_S) > 10 * CRUISE_M_S
    micro = DEFAULT_RIG.micro
    assert dot_radius_m(micro) == 35e-6
    assert max_trackable_speed_m_s(micro, EXPOSURE_S) == pytest.approx(0.01225)
    assert not trackable(micro, CRUISE_M_S, EXPOSURE_S)
    assert trackable(micro, CRUISE_M_S, 0.003)


def test_a_still_robot_is_captured_as_before():
    camera = DEFAULT_RIG.micro
    assert uncertainty_in_motion(camera, 0.4, 0.0, 0.0, EXPOSURE_S) == camera.uncertainty(0.4)
    still = camera.measure(0.1, 0.0, 0.4, np.random.default_rng(3))
    assert measure_in_motion(camera, 0.1, 0.0, 0.4, 0.0, 0.0, EXPOSURE_S,
                             np.random.default_rng(3)) == still


def test_the_spread_grows_along_the_travel_only_as_derived():
    camera = DEFAULT_RIG.micro
    radius = dot_radius_m(camera)
    speed = radius / EXPOSURE_S        # a streak one dot radius long
    assert blur_m(speed, EXPOSURE_S) == pytest.approx(radius)
    assert along_travel_factor(camera, speed, EXPOSURE_S) == pytest.approx(math.sqrt(4 / 3))
    still = camera.uncertainty(0.0)
    moving = uncertainty_in_motion(camera, 0.0, speed, 0.0, EXPOSURE_S)
    assert moving.x_sigma_m == pytest.approx(still.x_sigma_m * math.sqrt(4 / 3))
    assert moving.y_sigma_m == still.y_sigma_m
    assert moving.heading_sigma_rad == still.heading_sigma_rad
    # An acceleration shifts the streak's centroid by a * exposure^2 / 24.
    braking = uncertainty_in_motion(camera, 0.0, speed, 0.0, EXPOSURE_S, acceleration_m_s2=-24.0)
    assert braking.x_sigma_m == pytest.approx(math.hypot(moving.x_sigma_m, EXPOSURE_S ** 2))
    # Sampled: the extra noise is along the travel, of the stated size.
    samples = np.array([measure_in_motion(camera, 0.1, 0.0, 0.0, 0.0, speed, EXPOSURE_S,
                                          np.random.default_rng(seed))[:2]
                        for seed in range(2000)])
    moving_y = uncertainty_in_motion(camera, 0.0, 0.0, speed, EXPOSURE_S)
    assert samples[:, 1].std() == pytest.approx(moving_y.y_sigma_m, rel=0.1)
    assert samples[:, 0].std() == pytest.approx(still.x_sigma_m, rel=0.1)


def test_frames_are_stamped_at_mid_exposure_and_ready_after_their_delay():
    timing = CameraTiming(frame_rate_hz=50.0, exposure_s=0.004, delay_s=0.03, jitter_s=0.01)
    assert timing.stamp_s(10) == pytest.approx(0.202)
    ready = [timing.ready_s(frame, seed=1, camera='micro') for frame in range(200)]
    late = np.array(ready) - [timing.exposure_start_s(f) + 0.034 for f in range(200)]
    assert np.all((late >= 0.0) & (late <= 0.01)) and late.std() > 0.002
    assert ready == [timing.ready_s(frame, seed=1, camera='micro') for frame in range(200)]
    assert ready != [timing.ready_s(frame, seed=2, camera='micro') for frame in range(200)]
    assert timing.first_frame_after(0.2) == 10 and timing.first_frame_after(0.2001) == 11


@pytest.mark.parametrize(('values', 'said'), [
    ({'frame_rate_hz': 0.0}, 'frame_rate_hz must be a finite number > 0, got 0.0'),
    ({'exposure_s': -0.001}, 'exposure_s must be a finite number >= 0, got -0.001'),
    ({'delay_s': math.nan}, 'delay_s must be a finite number >= 0, got nan'),
    ({'frame_rate_hz': 500.0, 'exposure_s': 0.004},
     'exposure_s 0.004 is longer than a frame at 500.0 Hz'),
])
def test_a_timing_that_cannot_be_is_refused_naming_the_value(values, said):
    with pytest.raises(CameraConfigError, match=f'^{said}$'):
        CameraTiming(**values)


def moving_camera(**timings: CameraTiming) -> MovingCamera:
    return MovingCamera(DEFAULT_RIG, {'macro': timings.get('macro', CameraTiming()),
                                      'micro': timings.get('micro', CameraTiming())}, seed=4)


def feed(camera: MovingCamera, samples: list[tuple[float, ...]]) -> list[MotionCapture]:
    captures = []
    for sample in samples:
        captures += camera.on_odometry(*sample)
    return captures


def constant_velocity(start_s: float, end_s: float, v: float, x0: float = 0.02,
                      grid_s: float = 0.02) -> list[tuple[float, ...]]:
    count = round((end_s - start_s) / grid_s)
    return [(start_s + k * grid_s, x0 + v * k * grid_s, 0.0, 0.1, v, 0.0)
            for k in range(count + 1)]


def test_a_robot_rolling_through_the_macro_field_is_captured_every_frame_at_mid_exposure():
    samples = constant_velocity(0.0, 1.0, CRUISE_M_S)
    captures = feed(moving_camera(), samples)
    # Frames 0..29 of the 30 Hz camera have their middles inside the samples' span.
    assert [c.frame for c in captures] == list(range(30))
    assert all(c.camera == 'macro' for c in captures)
    assert [c.stamp_s for c in captures] == pytest.approx([k / 30 + 0.002 for k in range(30)])
    errors = np.array([c.x_m - (0.02 + CRUISE_M_S * c.stamp_s) for c in captures])
    stated = captures[0].uncertainty.x_sigma_m
    assert np.all(np.abs(errors) < 4 * stated) and errors.std() > 0.3 * stated
    assert feed(moving_camera(), samples) == captures           # a function of the seed


def test_a_still_robot_gives_no_capture_in_motion_and_the_micro_camera_needs_a_slow_robot():
    assert feed(moving_camera(), constant_velocity(0.0, 0.5, 0.0)) == []
    # In the micro field (centred at 100 mm): at cruise its streak is too long and the macro
    # camera speaks; at 5 mm/s the micro camera does.
    fast = feed(moving_camera(), constant_velocity(0.0, 0.1, CRUISE_M_S, x0=0.0995))
    assert fast and {c.camera for c in fast} == {'macro'}
    slow = feed(moving_camera(), constant_velocity(0.0, 0.1, 0.005, x0=0.0995))
    assert slow and {c.camera for c in slow} == {'micro'}
    assert all(abs(c.x_m - (0.0995 + 0.005 * c.stamp_s)) < 4 * c.uncertainty.x_sigma_m
               for c in slow)


def test_a_capture_is_released_once_time_has_reached_its_delay():
    late = CameraTiming(frame_rate_hz=50.0, delay_s=0.1)
    camera = moving_camera(macro=late)
    released = []
    for sample in constant_velocity(0.0, 0.5, CRUISE_M_S):
        for capture in camera.on_odometry(*sample):
            released.append((sample[0], capture))
    assert released and all(at >= capture.ready_s - 1e-9 and at - capture.ready_s < 0.02 + 1e-9
                            for at, capture in released)
    assert all(capture.ready_s == pytest.approx(capture.stamp_s + 0.002 + 0.1)
               for _, capture in released)


def test_captures_come_out_in_exposure_order_and_never_older_than_the_bound():
    # A jitter of three frames would let a later frame overtake an earlier one.
    jittery = CameraTiming(frame_rate_hz=60.0, delay_s=0.01, jitter_s=0.05)
    camera = moving_camera(macro=jittery)
    released = []
    for sample in constant_velocity(0.0, 1.0, CRUISE_M_S):
        released += [(sample[0], capture) for capture in camera.on_odometry(*sample)]
    stamps = [capture.stamp_s for _, capture in released]
    assert len(stamps) == 59 and stamps == sorted(stamps)
    ages = [at - capture.stamp_s for at, capture in released]
    bound = capture_age_bound_s([jittery, CameraTiming()], period_s=0.02)
    assert bound == pytest.approx(0.002 + 0.01 + 0.05 + 0.02)
    assert max(ages) <= bound + 1e-9
    # Some waited for an earlier frame: released after their own ready time's sample.
    assert any(at - capture.ready_s >= 0.02 - 1e-9 for at, capture in released)
