"""ROS 2 adapter of the tracker: camera images in, pose captures out (the camera contract).

Subscribes, per camera (``cameras``: macro, micro), a sensor_msgs/Image and its CameraInfo
(``<name>.image_topic``, ``<name>.info_topic``: remap them to a real driver's) and publishes, in
the ``platform`` frame:
  /camera/<name>/pose                    geometry_msgs/PoseStamped captures, stamped with the frame
  /camera/<name>/pose_with_covariance    the same, with the camera model's covariance
  /camera/<name>/tracker_status          diagnostic_msgs/DiagnosticStatus: why a frame gave no
                                         pose (fiducial not found, cut by the edge, ambiguous) or
                                         why it was refused (encoding, size), on each change
A capture is published only while the robot is still, decided from the images alone: the
fiducial's pose in the last ``still_frames`` frames agrees within ``still_tolerance_px`` pixels.
Where the camera looks is a parameter (``<name>.center_m``, ``<name>.field_m``: the platform
point under the image's centre and the field the image spans; the pixel size follows from the
image's size). The image processing is :mod:`omni_micro_vision.imaging`'s.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_sim.conventions import yaw_to_quaternion
from omni_micro_sim.node_runtime import run_node
from omni_micro_sim.qos import CAPTURE_COVARIANCE_TOPICS, CAPTURE_QOS, CAPTURE_TOPICS, latched
from omni_micro_vision.camera import DEFAULT_RIG, CameraConfigError, CameraModel
from omni_micro_vision.imaging import track

DTYPES = {'mono8': np.uint8, 'mono16': np.uint16}


def image_array(msg: Image, expected: tuple[int, int] | None) -> np.ndarray:
    """The pixels of ``msg`` as a rows x columns array.

    Raises
    ------
    CameraConfigError
        Naming what is wrong: the encoding, the size against the CameraInfo, the data length.
    """
    if msg.encoding not in DTYPES:
        raise CameraConfigError(f'encoding {msg.encoding!r} is not mono8 or mono16')
    if expected is not None and (msg.width, msg.height) != expected:
        raise CameraConfigError(f'image is {msg.width} x {msg.height}, its CameraInfo says '
                                f'{expected[0]} x {expected[1]}')
    dtype = np.dtype(DTYPES[msg.encoding]).newbyteorder('>' if msg.is_bigendian else '<')
    row_bytes = msg.width * dtype.itemsize
    if msg.step < row_bytes or len(msg.data) != msg.step * msg.height:
        raise CameraConfigError(f'{len(msg.data)} bytes of data for {msg.height} rows of step '
                                f'{msg.step} ({msg.width} pixels of {dtype.itemsize} bytes)')
    rows = np.frombuffer(bytes(msg.data), dtype=np.uint8).reshape(msg.height, msg.step)
    return rows[:, :row_bytes].copy().view(dtype).astype(DTYPES[msg.encoding])


class TrackerNode(Node):
    def __init__(self) -> None:
        super().__init__('tracker_node')
        self.frame_id = self.declare_parameter('frame_id', 'platform').value
        cameras = list(self.declare_parameter('cameras', ['macro', 'micro']).value)
        self.still_frames = int(self.declare_parameter('still_frames', 3).value)
        self.still_px = float(self.declare_parameter('still_tolerance_px', 0.5).value)
        if self.still_frames < 2 or not self.still_px > 0:
            raise CameraConfigError(f'still_frames must be >= 2 and still_tolerance_px > 0, got '
                                    f'{self.still_frames} and {self.still_px}')
        unknown = sorted(set(cameras) - set(CAPTURE_TOPICS))
        if unknown:
            raise CameraConfigError(f'cameras: {unknown[0]!r} is not one of '
                                    f'{sorted(CAPTURE_TOPICS)}')
        # Every camera's parameters are declared (one params file serves any choice of cameras);
        # only those in ``cameras`` are read.
        for name in CAPTURE_TOPICS:
            default: CameraModel = getattr(DEFAULT_RIG, name)
            center = self.declare_parameter(f'{name}.center_m', list(default.center_m)).value
            field = self.declare_parameter(f'{name}.field_m', list(default.field_m)).value
            image_topic = self.declare_parameter(f'{name}.image_topic',
                                                 f'/camera/{name}/image_raw').value
            info_topic = self.declare_parameter(f'{name}.info_topic',
                                                f'/camera/{name}/camera_info').value
            CameraModel(name, center, field)      # checks the pose parameters now
            if name not in cameras:
                continue
            reader = _CameraReader(self, name, center, field)
            self.create_subscription(Image, image_topic, reader.on_image, CAPTURE_QOS)
            self.create_subscription(CameraInfo, info_topic, reader.on_info, CAPTURE_QOS)
        self.get_logger().info(f'tracking {", ".join(cameras)}; a capture once '
                               f'{self.still_frames} frames agree within {self.still_px} px')


class _CameraReader:
    """One camera's frames: track, decide stillness, publish."""

    def __init__(self, node: TrackerNode, name: str, center: list[float],
                 field: list[float]) -> None:
        self.node = node
        self.name = name
        self.center = (float(center[0]), float(center[1]))
        self.field = (float(field[0]), float(field[1]))
        self.size: tuple[int, int] | None = None
        self.recent: deque[tuple[float, float, float]] = deque(maxlen=node.still_frames)
        self.capture_pub = node.create_publisher(PoseStamped, CAPTURE_TOPICS[name], CAPTURE_QOS)
        self.covariance_pub = node.create_publisher(
            PoseWithCovarianceStamped, CAPTURE_COVARIANCE_TOPICS[name], CAPTURE_QOS)
        self.status_pub = node.create_publisher(DiagnosticStatus,
                                                f'/camera/{name}/tracker_status', latched(1))
        self._said: str | None = None

    def on_info(self, msg: CameraInfo) -> None:
        self.size = (int(msg.width), int(msg.height))

    def _say(self, level: bytes, message: str) -> None:
        if message != self._said:
            self._said = message
            self.status_pub.publish(DiagnosticStatus(level=level, name=f'tracker {self.name}',
                                                     message=message))

    def camera(self, width: int, height: int) -> CameraModel:
        return CameraModel(self.name, self.center, self.field, (width, height))

    def on_image(self, msg: Image) -> None:
        try:
            pixels = image_array(msg, self.size)
        except CameraConfigError as error:
            self.node.get_logger().warning(f'{self.name}: frame refused: {error}')
            self._say(DiagnosticStatus.ERROR, f'frame refused: {error}')
            self.recent.clear()
            return
        camera = self.camera(msg.width, msg.height)
        result = track(pixels, camera)
        if result.pose is None:
            self.recent.clear()
            self._say(DiagnosticStatus.WARN, result.reason)
            return
        self.recent.append(result.pose)
        pixel = min(camera.pixel_size_m)
        if len(self.recent) < self.node.still_frames or any(
                math.hypot(x - result.pose[0], y - result.pose[1]) > self.node.still_px * pixel
                for x, y, _ in self.recent):
            self._say(DiagnosticStatus.OK, 'moving')
            return
        self._say(DiagnosticStatus.OK, 'still: capturing')
        self.publish(msg, camera, result.pose)

    def publish(self, msg: Image, camera: CameraModel,
                pose: tuple[float, float, float]) -> None:
        capture = PoseStamped()
        capture.header.stamp = msg.header.stamp
        capture.header.frame_id = self.node.frame_id
        capture.pose.position.x, capture.pose.position.y = pose[0], pose[1]
        capture.pose.orientation.z, capture.pose.orientation.w = yaw_to_quaternion(pose[2])
        covariance = PoseWithCovarianceStamped()
        covariance.header = capture.header
        covariance.pose.pose = capture.pose
        covariance.pose.covariance = camera.uncertainty(pose[2]).covariance()
        self.capture_pub.publish(capture)
        self.covariance_pub.publish(covariance)


def main(args: list[str] | None = None) -> None:
    run_node(TrackerNode, config_errors=(CameraConfigError,), args=args)


if __name__ == '__main__':
    main()
