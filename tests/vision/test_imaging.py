"""Images of the robot and the tracker that reads them (omni_micro_vision.rendering): accuracy
against the true pose beside the analytic camera model, the reasons a frame gives no pose, and
frames that are a function of their seed."""

import math

import numpy as np
import pytest

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG, checked_yaw
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import PlaneMap
from omni_micro_vision.rendering import Sensor, render
from omni_micro_vision.tracking import track

SENSOR = Sensor()
SAMPLES = 24


@pytest.mark.parametrize(('camera', 'half_range_m'), [(DEFAULT_RIG.macro, 0.06),
                                                     (DEFAULT_RIG.micro, 0.0005)],
                         ids=['macro', 'micro'])
def test_tracker_bias_and_spread_beside_the_analytic_model(camera, half_range_m):
    """Over poses and headings across the field: the spread within 2x of what vision_node's
    model states, the bias within its own sampling error."""
    rng = np.random.default_rng(11)
    errors = []
    for sample in range(SAMPLES):
        x = camera.center_m[0] + rng.uniform(-half_range_m, half_range_m)
        y = camera.center_m[1] + rng.uniform(-half_range_m, half_range_m)
        phi = rng.uniform(-math.pi, math.pi)
        result = track(render(camera, SENSOR, RobotState(x, y, phi),
                              np.random.default_rng([11, sample])), PlaneMap.nominal(camera))
        assert result.pose is not None, result.reason
        found_x, found_y, found_phi = result.pose
        errors.append((found_x - x, found_y - y, math.remainder(found_phi - phi, 2 * math.pi)))
    errors_array = np.array(errors)
    spread = errors_array.std(axis=0)
    bias = errors_array.mean(axis=0)
    model = camera.uncertainty(0.0)
    stated = np.array([model.x_sigma_m, model.y_sigma_m, model.heading_sigma_rad])
    assert np.all(spread <= 2.0 * stated), (spread, stated)
    assert np.all(np.abs(bias) <= 4.0 * spread / math.sqrt(SAMPLES) + 0.05 * stated), bias


def test_frames_are_a_function_of_their_seed_and_motion_blurs_them():
    camera = DEFAULT_RIG.macro
    still = RobotState(0.05, 0.0, 0.2)
    first = render(camera, SENSOR, still, np.random.default_rng([3, 7]))
    assert first.dtype == np.uint8 and first.shape == (1024, 1280)
    assert np.array_equal(first, render(camera, SENSOR, still, np.random.default_rng([3, 7])))
    assert not np.array_equal(first, render(camera, SENSOR, still,
                                            np.random.default_rng([3, 8])))
    # At cruise speed (14 mm/s) over a 4 ms exposure the robot moves 57 um, half a macro pixel;
    # at 100x that, the dots smear over 50 pixels and the frame is no use.
    moving = RobotState(0.05, 0.0, 0.2, vx_m_s=1.4)
    smeared = render(camera, SENSOR, moving, np.random.default_rng([3, 7]))
    assert smeared.max() < first.max()
    assert not track(smeared, PlaneMap.nominal(camera)).found


def test_a_mono16_frame_tracks_as_well():
    camera = DEFAULT_RIG.micro
    sensor = Sensor(bit_depth=16)
    assert sensor.encoding == 'mono16'
    frame = render(camera, sensor, RobotState(0.1001, 0.0002, 2.0), np.random.default_rng(1))
    assert frame.dtype == np.uint16 and frame.max() > 255
    result = track(frame, PlaneMap.nominal(camera))
    assert result.pose is not None
    assert math.hypot(result.pose[0] - 0.1001, result.pose[1] - 0.0002) < 0.05e-6


@pytest.mark.parametrize(('pose', 'reason'), [
    ((0.1007, 0.0, 0.0), 'fiducial cut by the edge of the micro field'),   # front dot on it
    ((0.1009, 0.0, 0.0), 'fiducial not found: no front dot of the expected size (3706 px)'),
    ((0.1, 0.05, 0.0), 'no fiducial: nothing brighter than the platform'),
], ids=['cut-by-the-edge', 'front-dot-outside', 'robot-out-of-view'])
def test_a_frame_without_a_whole_fiducial_gives_no_pose_and_says_why(pose, reason):
    camera = DEFAULT_RIG.micro
    frame = render(camera, SENSOR, RobotState(*pose), np.random.default_rng(2))
    result = track(frame, PlaneMap.nominal(camera))
    assert not result.found and result.pose is None
    assert result.reason == reason


def test_a_corrupt_or_wrongly_sized_frame_is_refused_naming_the_problem():
    camera = DEFAULT_RIG.macro
    with pytest.raises(CameraConfigError, match=r'expected a 1280 x 1024 mono image, got '
                                                r'shape \(1024, 1000\)'):
        track(np.zeros((1024, 1000), dtype=np.uint8), PlaneMap.nominal(camera))
    with pytest.raises(CameraConfigError, match='got shape'):
        track(np.zeros((1024, 1280, 3), dtype=np.uint8), PlaneMap.nominal(camera))
    with pytest.raises(CameraConfigError, match='bit_depth must be 8'):
        Sensor(bit_depth=12)


@pytest.mark.parametrize('camera', [DEFAULT_RIG.macro, DEFAULT_RIG.micro], ids=['macro', 'micro'])
def test_a_search_near_the_last_pose_finds_what_the_whole_frame_shows(camera):
    """The window around the last pose is only a shortcut: the same pose (to a hundredth of the
    tracker's spread), and a wrong guess falls back to the whole frame."""
    x = camera.center_m[0] + 0.2 * camera.field_m[0]
    y = camera.center_m[1] - 0.1 * camera.field_m[1]
    frame = render(camera, SENSOR, RobotState(x, y, 1.0), np.random.default_rng(5))
    whole = track(frame, PlaneMap.nominal(camera))
    assert whole.pose is not None
    spread = camera.uncertainty(1.0).x_sigma_m
    for guess in ((x + 0.05 * spread, y), (camera.center_m[0] - 0.4 * camera.field_m[0],
                                           camera.center_m[1] + 0.4 * camera.field_m[1])):
        near = track(frame, PlaneMap.nominal(camera), near=guess)
        assert near.pose is not None
        assert math.hypot(near.pose[0] - whole.pose[0], near.pose[1] - whole.pose[1]) \
            < 0.01 * spread


def test_a_turned_camera_is_tracked_in_the_platform_frame_once_its_yaw_is_known():
    """A mount 1 deg off square: read with its yaw, the pose is right to the tracker's spread;
    read as if square, the micro camera is off by tens of um at 0.6 mm from its centre."""
    camera = DEFAULT_RIG.micro
    yaw = math.radians(1.0)
    x, y, phi = camera.center_m[0] + 0.6e-3, camera.center_m[1] + 0.2e-3, 0.4
    frame = render(camera, SENSOR, RobotState(x, y, phi), np.random.default_rng(9), yaw)
    known = track(frame, PlaneMap.nominal(camera, yaw))
    assert known.pose is not None
    assert math.hypot(known.pose[0] - x, known.pose[1] - y) < 0.05e-6
    assert abs(known.pose[2] - phi) < 1e-3
    square = track(frame, PlaneMap.nominal(camera))
    assert square.pose is not None and math.hypot(square.pose[0] - x, square.pose[1] - y) > 5e-6
    assert abs(square.pose[2] - (phi - yaw)) < 1e-3
    with pytest.raises(CameraConfigError, match=r'micro.yaw_rad must be finite and within'):
        checked_yaw('micro.yaw_rad', float('nan'))
