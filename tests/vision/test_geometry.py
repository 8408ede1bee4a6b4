"""A camera's pixels on the platform (omni_micro_vision.geometry, optics, tracked_camera): a
camera mounted as a real one is (any turn, mirrored, another sensor, a distorting lens) is
tracked right through its true map, and a driver's CameraInfo that contradicts the geometry
the tracker holds is refused with both values named, never tracked into a wrong pose."""

import math

import numpy as np
import pytest

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel
from omni_micro_vision.camera_frames import CameraFrames
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import Lens, PlaneMap
from omni_micro_vision.optics import CameraOptics
from omni_micro_vision.rendering import Sensor
from omni_micro_vision.tracked_camera import tracked_camera
from omni_micro_vision.tracking import track

# The real cameras over the micro field: 1280 x 1024 pixels of 1.72 um, 2448 x 2048 of
# 1 um (on the platform).
SENSORS = {'1280x1024 at 1.72 um': ((1280, 1024), 1.72e-6),
           '2448x2048 at 1 um': ((2448, 2048), 1.0e-6)}


def micro(resolution: tuple[int, int], pixel_m: float) -> CameraModel:
    return CameraModel('micro', (0.1, 0.0), (resolution[0] * pixel_m, resolution[1] * pixel_m),
                       resolution)


@pytest.mark.parametrize('mirrored', [False, True])
@pytest.mark.parametrize('yaw_deg', [0.0, 90.0, -135.0])
def test_a_nominal_map_and_its_inverse_agree_and_keep_the_handedness(yaw_deg, mirrored):
    plane = PlaneMap.nominal(DEFAULT_RIG.macro, math.radians(yaw_deg), mirrored,
                             Lens((2560.0, 0, 639.5, 0, 2048.0, 511.5, 0, 0, 1),
                                  (-0.2, 0.05, 0, 0, 0)))
    pixels = np.array([[0.0, 0.0], [639.5, 511.5], [1279.0, 1023.0], [100.25, 900.75]])
    np.testing.assert_allclose(plane.to_pixels(plane.to_platform(pixels)), pixels, atol=1e-6)
    # A camera looking down sees the platform's y against its v: mirrored is the other way.
    assert plane.mirrored == mirrored
    np.testing.assert_allclose(plane.centre_m, DEFAULT_RIG.macro.center_m, atol=1e-12)


@pytest.mark.parametrize('sensor', SENSORS, ids=list(SENSORS))
@pytest.mark.parametrize(('yaw_deg', 'mirrored', 'distortion'), [
    (90.0, False, (0.0, 0.0)), (1.0, True, (0.0, 0.0)), (-30.0, False, (-0.3, 0.1))],
    ids=['turned-90', 'mirrored', 'lens'])
def test_a_camera_mounted_as_a_real_one_is_tracked_through_its_true_map(sensor, yaw_deg,
                                                                        mirrored, distortion):
    resolution, pixel_m = SENSORS[sensor]
    # A short working distance so that the lens bends the micro field visibly: k1 = -0.3
    # moves the corner pixels by 1 % (7-12 pixels).
    optics = CameraOptics(micro(resolution, pixel_m), math.radians(yaw_deg), mirrored, 0.006,
                          distortion)
    frames = CameraFrames(1, optics, Sensor(), 0)
    for index, truth in enumerate([(0.1002, 0.0003, 2.0), (0.0996, -0.0002, -0.7)]):
        found = track(frames.pixels(index, RobotState(*truth)), optics.plane)
        assert found.pose is not None, found.reason
        # Within 5 % of a pixel, half what vision_node's model states per mark (the tracker's
        # own spread is 0.5 %; through the lens, the remap interpolates the frame's noise and a
        # bent dot's centroid shifts by up to 3.5 % measured).
        assert math.hypot(found.pose[0] - truth[0], found.pose[1] - truth[1]) < 0.05 * pixel_m
        assert abs(math.remainder(found.pose[2] - truth[2], math.tau)) < 0.2e-3
    if any(distortion):
        # The same frames read as if the lens were perfect: micrometres off.
        ideal = PlaneMap.nominal(optics.camera, optics.yaw_rad, mirrored)
        found = track(frames.pixels(0, RobotState(0.1004, 0.0003, 2.0)), ideal)
        assert found.pose is not None
        assert math.hypot(found.pose[0] - 0.1004, found.pose[1] - 0.0003) > 1e-6


def settings(values: dict[str, object]):
    return lambda key, default: values.get(key, default)


def test_a_camera_info_that_contradicts_the_nominal_geometry_is_refused_naming_both():
    camera = tracked_camera('micro', settings({}))
    lens = CameraOptics(DEFAULT_RIG.micro, working_distance_m=0.04).lens
    # camera_node's own CameraInfo agrees with the nominal geometry it renders.
    assert camera.refusal(1280, 1024, lens.camera_matrix, lens.distortion) is None
    assert camera.refusal(1280, 1024, [0.0] * 9, []) is None   # an uncalibrated driver
    assert camera.refusal(2448, 2048, [0.0] * 9, []) == (
        'CameraInfo says 2448 x 2048 pixels, the nominal geometry (no calibration) is for '
        '1280 x 1024')
    # A real 1280 x 1024 camera of square pixels where the nominal field has them 1.56 x 1.95.
    square = [25000.0, 0, 639.5, 0, 25000.0, 511.5, 0, 0, 1]
    assert str(camera.refusal(1280, 1024, square, [0.0] * 5)).startswith(
        'CameraInfo fx/fy = 1, but the nominal field and resolution make pixels of 1.562 x '
        '1.953 um (fx/fy 1.25)')
    assert camera.refusal(1280, 1024, lens.camera_matrix, [-0.1, 0, 0, 0, 0]) == (
        'CameraInfo has lens distortion D [-0.1, 0, 0, 0, 0] and micro has no calibration: '
        'run omni-micro calibrate-camera')


def test_a_camera_info_that_contradicts_the_calibration_is_refused_naming_both():
    optics = CameraOptics(micro((1280, 1024), 1.72e-6), 0.2, False, 0.04, (-0.1, 0.0))
    plane = optics.plane
    camera = tracked_camera('micro', settings({
        'micro.calibration.resolution_px': [1280, 1024],
        'micro.calibration.camera_matrix': list(plane.lens.camera_matrix),
        'micro.calibration.distortion': list(plane.lens.distortion),
        'micro.calibration.homography': list(plane.homography),
        'micro.calibration.residual_px': 0.05, 'micro.calibration.residual_m': 8e-8}))
    assert camera.calibrated and camera.plane.residual_m == 8e-8
    assert camera.refusal(1280, 1024, plane.lens.camera_matrix, plane.lens.distortion) is None
    other = list(plane.lens.camera_matrix)
    other[0] *= 1.01
    refusal = camera.refusal(1280, 1024, other, plane.lens.distortion)
    assert refusal is not None and refusal.startswith('CameraInfo K [23488.4, ') \
        and 'differs from the calibrated K [23255.8, ' in refusal
    assert 'calibrate again (omni-micro calibrate-camera)' in refusal
    assert 'is for 1280 x 1024' in str(camera.refusal(1024, 768, other, []))
    # The stated spread grows by the calibration's residual on the platform.
    plain = camera.model.uncertainty(0.3)
    stated = camera.uncertainty(0.3)
    assert stated.x_sigma_m == pytest.approx(math.hypot(plain.x_sigma_m, 8e-8 / math.sqrt(2)))
    assert stated.heading_sigma_rad > plain.heading_sigma_rad


@pytest.mark.parametrize(('values', 'match'), [
    ({'micro.calibration.homography': [1.0] * 9}, 'has a homography but no resolution_px or '
                                                  'camera_matrix'),
    ({'micro.calibration.homography': [0.0] * 9, 'micro.calibration.resolution_px': [4, 4],
      'micro.calibration.camera_matrix': [0.0] * 9}, 'micro.homography is singular'),
    ({'micro.mirrored': 'yes'}, "micro.mirrored must be true or false, got 'yes'"),
    ({'micro.bit_depth': 9}, 'micro.bit_depth must be 0'),
], ids=['no-lens', 'singular', 'mirrored-not-bool', 'bit-depth'])
def test_settings_that_cannot_make_a_geometry_are_refused_naming_them(values, match):
    with pytest.raises(CameraConfigError, match=match):
        tracked_camera('micro', settings(values))


def test_a_calibration_mapping_a_mirrored_image_must_say_so():
    plane = PlaneMap.nominal(DEFAULT_RIG.micro, 0.0, True)
    with pytest.raises(CameraConfigError, match=r'micro.mirrored is false but the calibration '
                                                r'maps a mirrored image'):
        tracked_camera('micro', settings({
            'micro.calibration.resolution_px': [1280, 1024],
            'micro.calibration.camera_matrix': [0.0] * 9,
            'micro.calibration.homography': list(plane.homography)}))
