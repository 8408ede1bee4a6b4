"""tracker_node with a calibration (in-process): a camera mounted as a real one is, its frames
and CameraInfo as its driver sends them, read into captures where the robot is; a CameraInfo
that contradicts the calibration gets every frame refused, both values named, no capture."""

from __future__ import annotations

import math

from rclpy.parameter import Parameter

from omni_micro_common.conventions import quaternion_to_yaw
from omni_micro_sim.state import RobotState
from omni_micro_vision.calibration import calibrate
from omni_micro_vision.camera_frames import CameraFrames, camera_settings
from omni_micro_vision.geometry import Lens
from omni_micro_vision.image_messages import ImageWriter
from omni_micro_vision.targets import Chessboard
from omni_micro_vision.tracker_node import TrackerNode

MOUNT = {'micro.yaw_rad': -2.0, 'micro.mirrored': True, 'micro.resolution_px': [1280, 1024],
         'micro.field_m': [1280 * 1.72e-6, 1024 * 1.72e-6], 'micro.working_distance_m': 0.006,
         'micro.distortion': [-0.2, 0.0]}
TARGET = Chessboard((9, 6), 0.12e-3, (0.1, 0.0002), 0.3)


def calibration_parameters() -> list[Parameter]:
    optics, sensor = camera_settings('micro', MOUNT.get)
    frames = CameraFrames(1, optics, sensor, 0, TARGET)
    fitted = calibrate('micro', [frames.pixels(i, RobotState(0.0, 0.0, 0.0)) for i in range(3)],
                       optics.lens, TARGET, True).plane
    values = {'cameras': ['micro'], 'micro.mirrored': True,
              'micro.calibration.resolution_px': list(fitted.resolution_px),
              'micro.calibration.camera_matrix': list(fitted.lens.camera_matrix),
              'micro.calibration.distortion': list(fitted.lens.distortion),
              'micro.calibration.homography': list(fitted.homography),
              'micro.calibration.residual_px': fitted.residual_px,
              'micro.calibration.residual_m': fitted.residual_m}
    return [Parameter(name, value=value) for name, value in values.items()]


def test_a_calibrated_tracker_captures_a_mounted_camera_where_the_robot_is(context, spy):
    node = TrackerNode(context=context, parameter_overrides=calibration_parameters())
    try:
        reader = node.readers[0]
        captures, covariances = spy(reader.capture_pub), spy(reader.covariance_pub)
        statuses = spy(reader.status_pub)
        optics, sensor = camera_settings('micro', MOUNT.get)
        frames = CameraFrames(1, optics, sensor, 0)
        truth = RobotState(0.1003, -0.0002, 0.8)
        for number in range(4):
            info, image = frames.messages(number, 0, number * 33_333_333, truth)
            reader.on_info(_decoded_info(info))
            reader.on_image(image)
        assert len(captures.messages) == 2, [s.message for s in statuses.messages]
        for capture in captures.messages:
            position = capture.pose.position
            assert math.hypot(position.x - truth.x_m, position.y - truth.y_m) < 0.1e-6
            heading = quaternion_to_yaw(capture.pose.orientation.z, capture.pose.orientation.w)
            assert abs(math.remainder(heading - truth.phi_rad, math.tau)) < 0.3e-3
        # The covariance states the calibration's residual beside the pixel noise.
        assert covariances.messages[0].pose.covariance[0] > reader.camera.model.uncertainty(
            0.8).x_sigma_m ** 2
        # The driver's CameraInfo now says another lens: every frame refused, no capture.
        other = Lens(optics.lens.camera_matrix, (-0.25, 0.0, 0.0, 0.0, 0.0))
        writer = ImageWriter('micro_optical_frame', 1024, 1280, 'mono8', other)
        reader.on_info(_decoded_info(writer.info(0, 5 * 33_333_333)))
        for number in range(5, 9):
            reader.on_image(frames.messages(number, 0, number * 33_333_333, truth)[1])
        assert len(captures.messages) == 2
        message = statuses.messages[-1].message
        assert message.startswith('frame refused: CameraInfo K [')
        assert 'D [-0.25, 0, 0, 0, 0] differs from the calibrated K [' in message
        assert 'D [-0.2, 0, 0, 0, 0]' in message
    finally:
        node.destroy_node()


def _decoded_info(data: bytes):
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import CameraInfo

    return deserialize_message(data, CameraInfo)
