"""The bench procedure rehearsed in simulation: a camera mounted as a real one is (turned,
mirrored, another sensor, a distorting lens), its frames of a chessboard recorded
(record-target), its map fitted (calibrate-camera), and the tracker given that params file
reads the robot where it is; and what calibrate-camera refuses."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from omni_micro_common.params import node_parameters
from omni_micro_sim.state import RobotState
from omni_micro_vision.calibration import CalibrationError, calibrate
from omni_micro_vision.camera_frames import CameraFrames, camera_settings
from omni_micro_vision.geometry import Lens
from omni_micro_vision.rendering import Sensor
from omni_micro_vision.targets import Chessboard, CircleGrid, Target
from omni_micro_vision.tracked_camera import tracked_camera
from omni_micro_vision.tracking import track

ROOT = Path(__file__).resolve().parents[2]
# A real camera over the micro field: 1.72 um pixels on the platform, turned 1.2 rad, mirrored,
# and a lens that bends the corners by 1 %.
MOUNT = {'micro.yaw_rad': 1.2, 'micro.mirrored': True, 'micro.resolution_px': [1280, 1024],
         'micro.field_m': [1280 * 1.72e-6, 1024 * 1.72e-6], 'micro.working_distance_m': 0.006,
         'micro.distortion': [-0.3, 0.1]}
TARGET = ['--target-center-mm', '100.1,0', '--target-yaw-deg', '10', '--pitch-mm', '0.12']


def omni_micro(*args):
    return subprocess.run([sys.executable, '-m', 'omni_micro_cli', *args], cwd=ROOT,
                          capture_output=True, text=True)


def mount_file(path: Path) -> Path:
    lines = ['camera_node:', '  ros__parameters:', '    micro:']
    for key, value in MOUNT.items():
        text = str(value).lower() if isinstance(value, bool) else str(value)
        lines.append(f'      {key.split(".", 1)[1]}: {text}')
    path.write_text('\n'.join(lines) + '\n')
    return path


@pytest.mark.slow
def test_the_procedure_finds_the_mount_and_the_tracker_reads_the_robot_where_it_is(tmp_path):
    bag, calibration = tmp_path / 'target', tmp_path / 'micro_calibration.yaml'
    recorded = omni_micro('record-target', '--camera', 'micro', '--out', str(bag), '--params',
                          str(mount_file(tmp_path / 'camera.yaml')), *TARGET)
    assert recorded.returncode == 0, recorded.stderr
    fitted = omni_micro('calibrate-camera', str(bag), '--out', str(calibration), '--mirrored',
                        *TARGET)
    assert fitted.returncode == 0, fitted.stderr
    residual_px = float(fitted.stdout.split('RMS residual ')[1].split(' px')[0])
    assert 0 < residual_px < 0.1
    camera = tracked_camera('micro', node_parameters([calibration], 'tracker_node').get)
    assert camera.calibrated and camera.plane.mirrored
    # The robot, seen by the same camera, where the calibration says.
    optics, sensor = camera_settings('micro', MOUNT.get)
    frames = CameraFrames(1, optics, sensor, 0)
    for index, truth in enumerate([(0.1002, 0.0003, 2.0), (0.0997, -0.0001, -0.7)]):
        found = track(frames.pixels(index, RobotState(*truth)), camera.plane)
        assert found.pose is not None, found.reason
        assert math.hypot(found.pose[0] - truth[0], found.pose[1] - truth[1]) < 0.1e-6
        assert abs(math.remainder(found.pose[2] - truth[2], math.tau)) < 0.3e-3
    # Said as not mirrored, it is refused by the tracker: the file says what it maps.
    wrong = node_parameters([calibration], 'tracker_node')
    wrong['micro.mirrored'] = False
    with pytest.raises(ValueError, match=r'micro.mirrored is false but the calibration maps a '
                                         r'mirrored image'):
        tracked_camera('micro', wrong.get)
    # A bag without the target: one line, exit 1, no file.
    missing = omni_micro('calibrate-camera', str(bag), '--out', str(tmp_path / 'none.yaml'),
                         '--pattern', '7x4', *TARGET)
    assert missing.returncode == 1
    assert missing.stderr.strip().splitlines() == [
        'omni-micro calibrate-camera: no chessboard of 7x4 inner corners found in the 10 '
        'frames: check --pattern (COLSxROWS, as OpenCV counts them) and that the whole target '
        'and its white border are in the image']
    assert not (tmp_path / 'none.yaml').exists()


TARGET_ON_MICRO = Chessboard((9, 6), 0.12e-3, (0.1001, 0.0), math.radians(10))


def target_frames(target: Target, settings: dict) -> tuple[list[np.ndarray], Lens]:
    optics, sensor = camera_settings('micro', settings.get)
    frames = CameraFrames(1, optics, sensor, 0, target)
    return [frames.pixels(i, RobotState(0.0, 0.0, 0.0)) for i in range(4)], optics.lens


def test_a_board_that_looks_the_same_turned_half_a_turn_is_refused():
    with pytest.raises(CalibrationError, match='a chessboard of 8x6 inner corners looks the same '
                                               'turned half a turn'):
        calibrate('micro', [np.zeros((8, 8), np.uint8)], Lens(),
                  Chessboard((8, 6), 1e-4, (0.1, 0.0)), False)


def test_a_lens_the_camera_info_does_not_state_makes_a_poor_fit_refused():
    """A strong lens (the target's corners bent by several pixels) fitted as if there were
    none: refused. (A mild one fits at 0.16 px against 0.03 px, within the line: its residual
    is then stated in every capture's covariance.)"""
    strong = {**MOUNT, 'micro.yaw_rad': 0.3, 'micro.working_distance_m': 0.003}
    frames, lens = target_frames(TARGET_ON_MICRO, strong)
    assert calibrate('micro', frames, lens, TARGET_ON_MICRO, True).plane.residual_px < 0.1
    with pytest.raises(CalibrationError, match=r'a poor fit: the points miss by [0-9.]+ px RMS '
                                               r'\(at most 0.5 px\)'):
        calibrate('micro', frames, Lens(), TARGET_ON_MICRO, True)


def test_without_a_lens_the_map_is_fitted_to_the_frames_own_pixels():
    plain = {key: value for key, value in MOUNT.items() if key != 'micro.distortion'}
    frames, _ = target_frames(TARGET_ON_MICRO, {**plain, 'micro.mirrored': False})
    fitted = calibrate('micro', frames, Lens(), TARGET_ON_MICRO, False).plane
    optics, _ = camera_settings('micro', {**plain, 'micro.mirrored': False}.get)
    pixels = np.array([[400.0, 300.0], [639.5, 511.5], [900.0, 700.0]])
    np.testing.assert_allclose(fitted.to_platform(pixels), optics.plane.to_platform(pixels),
                               atol=0.05e-6)
    assert not fitted.mirrored and fitted.residual_px < 0.1


def test_the_frames_are_what_camera_node_publishes():
    """record-target and camera_node's scene: chessboard are one function of the frame number;
    the bytes carry the true CameraInfo."""
    optics, _ = camera_settings('micro', MOUNT.get)
    frames = CameraFrames(1, optics, Sensor(), 0, TARGET_ON_MICRO)
    info, image = frames.messages(2, 0, 66_666_667, RobotState(0.0, 0.0, 0.0))
    again = CameraFrames(1, optics, Sensor(), 0, TARGET_ON_MICRO)
    assert again.messages(2, 0, 66_666_667, RobotState(0.0, 0.0, 0.0)) == (info, image)
    assert b'micro_optical_frame' in info and b'plumb_bob' in info


CIRCLES_ON_MICRO = CircleGrid((4, 11), 0.06e-3, (0.10005, 0.0), math.radians(20))


def test_an_asymmetric_circle_grid_calibrates_the_mounted_camera():
    """OpenCV's other standard target: its staggered rows tell which way it lies, so of the
    readings with the stated handedness only the true one fits."""
    frames, lens = target_frames(CIRCLES_ON_MICRO, MOUNT)
    fitted = calibrate('micro', frames, lens, CIRCLES_ON_MICRO, True).plane
    optics, _ = camera_settings('micro', MOUNT.get)
    pixels = np.array([[400.0, 300.0], [639.5, 511.5], [900.0, 700.0]])
    np.testing.assert_allclose(fitted.to_platform(pixels), optics.plane.to_platform(pixels),
                               atol=0.05e-6)
    assert fitted.mirrored and fitted.residual_px < 0.1
    with pytest.raises(CalibrationError, match='a circle grid of 4x10 with an even number of '
                                               'rows looks the same turned half a turn'):
        calibrate('micro', frames, lens, CircleGrid((4, 10), 0.06e-3, (0.1, 0.0)), True)
