"""ROS 2 adapter of the tracker: camera images in, pose captures out (the camera contract).

Subscribes, per camera (``cameras``: macro, micro), a sensor_msgs/Image and its CameraInfo
(``<name>.image_topic``, ``<name>.info_topic``: remap them to a real driver's) and publishes, in
the ``platform`` frame:
  /camera/<name>/pose                    geometry_msgs/PoseStamped captures, stamped with the frame
  /camera/<name>/pose_with_covariance    the same, with the covariance of vision_node's camera
                                         model (``<name>.noise_px``, ``<name>.quantisation_px``)
  /camera/<name>/tracker_status          diagnostic_msgs/DiagnosticStatus: why a frame gave no
                                         pose (fiducial not found, cut by the edge, ambiguous) or
                                         why it was refused (encoding, size), on each change
  /lockstep                              after each frame: up to which stamp every camera's
                                         frames are handled, and the captures that caused
A capture is published only while the robot is still, decided from the images alone: the
fiducial's pose in the last ``still_frames`` frames agrees within ``still_tolerance_px`` pixels;
and only from the finest camera that sees the robot (:mod:`omni_micro_vision.tracking`).
Where the camera looks is a parameter (``<name>.center_m``, ``<name>.field_m``: the platform
point under the image's centre and the field the image spans; the pixel size follows from the
image's size). The image processing is :mod:`omni_micro_vision.rendering`'s.
It reads images only once its capture writers have matched the readers of the nodes named in
``capture_readers`` (bare captures) and ``covariance_readers`` (empty when started alone), so
that none of them misses the first captures.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_common.conventions import stamp_ns, yaw_to_quaternion
from omni_micro_common.lockstep import Ack
from omni_micro_common.node_runtime import (
    LockstepReporter,
    NodeComponent,
    run_component,
    when_capture_readers_matched,
)
from omni_micro_common.qos import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_QOS,
    CAPTURE_TOPICS,
    IMAGE_QOS,
    latched,
)
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel, checked_cameras, checked_yaw
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fiducial import fiducial_for
from omni_micro_vision.image_messages import ImageLike, image_array, read_image
from omni_micro_vision.tracking import CameraArbiter, FrameTracker, StillnessRule

RELIABILITIES = {'reliable': ReliabilityPolicy.RELIABLE,
                 'best_effort': ReliabilityPolicy.BEST_EFFORT}



class TrackerNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options (context, parameter_overrides, ...) as rclpy's Node takes them: tests
        # build the node in-process with them.
        super().__init__('tracker_node', **node_options)
        self.frame_id = self.declare_parameter('frame_id', 'platform').value
        cameras = list(self.declare_parameter('cameras', ['macro', 'micro']).value)
        self.still_frames = int(self.declare_parameter('still_frames', 3).value)
        self.still_px = float(self.declare_parameter('still_tolerance_px', 0.2).value)
        if self.still_frames < 2 or not self.still_px > 0:
            raise CameraConfigError(f'still_frames must be >= 2 and still_tolerance_px > 0, got '
                                    f'{self.still_frames} and {self.still_px}')
        checked_cameras(cameras)
        reliability = self.declare_parameter('image_reliability', 'reliable').value
        if reliability not in RELIABILITIES:
            raise CameraConfigError(f'image_reliability must be one of {sorted(RELIABILITIES)}, '
                                    f'got {reliability!r}')
        image_qos = QoSProfile(depth=IMAGE_QOS.depth, reliability=RELIABILITIES[reliability])
        self.lockstep = LockstepReporter(self)
        self.readers: list[_CameraReader] = []
        inputs: list[tuple[str, str, _CameraReader]] = []
        fields: dict[str, float] = {}
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
            # The spread the published covariance states (vision_node's model): set them to
            # what `omni-micro track` measures on a real camera's still frames.
            noise = self.declare_parameter(f'{name}.noise_px', default.noise_px).value
            quantisation = self.declare_parameter(f'{name}.quantisation_px',
                                                  default.quantisation_px).value
            # How the camera is turned about its centre (its image's x against the platform's).
            yaw = checked_yaw(f'{name}.yaw_rad',
                              self.declare_parameter(f'{name}.yaw_rad', 0.0).value)
            # Checks the parameters now, whichever cameras are used.
            model = CameraModel(name, center, field, default.resolution_px, noise, quantisation)
            # The heading's spread follows from the baseline of the pair this camera tracks.
            model = dataclasses.replace(model, marker_baseline_m=fiducial_for(model).baseline_m)
            if name not in cameras:
                continue
            reader = _CameraReader(self, model, yaw)
            self.readers.append(reader)
            fields[name] = min(model.field_m)
            inputs.append((image_topic, info_topic, reader))
        # The smaller field has the finer pixel (the resolution comes with the images).
        self.arbiter: CameraArbiter[_Capture] = CameraArbiter(
            sorted(fields, key=fields.__getitem__))

        def read_images() -> None:
            for image_topic, info_topic, reader in inputs:
                # Raw: the pixels are read where they lie (image_messages.read_image).
                self.create_subscription(Image, image_topic, reader.on_image, image_qos,
                                         raw=True)
                self.create_subscription(CameraInfo, info_topic, reader.on_info, image_qos)

        # The nodes that must not miss a capture, by the topics they read (empty when started
        # alone): the images are read, and the camera (whose frames wait for these readers),
        # then the robot's clock, start only once the capture writers have matched them.
        when_capture_readers_matched(self, [reader.capture_pub for reader in self.readers],
                                     [reader.covariance_pub for reader in self.readers],
                                     read_images)
        self.get_logger().info(f'tracking {", ".join(cameras)}; a capture once '
                               f'{self.still_frames} frames agree within {self.still_px} px')

    def on_frame(self, reader: _CameraReader, stamp: int, found: bool,
                 capture: _Capture | None) -> None:
        """Publish what is due, then report: every camera's frames are handled up to the oldest
        of their latest (a capture from a frame still on its way could come later)."""
        reader.handled_ns = max(reader.handled_ns, stamp)
        due = self.arbiter.on_frame(reader.name, stamp, found, capture)
        for _, (owner, covariance, pose) in due:
            # The uncertainty first, as vision_node: a reader of the bare capture has it by then.
            owner.covariance_pub.publish(covariance)
            owner.capture_pub.publish(pose)
        self.lockstep.report(Ack(
            self.get_name(), None, captures_ns=(due[0][0], due[-1][0]) if due else None,
            frame_handled_ns=min(r.handled_ns for r in self.readers)))


class _CameraReader:
    """One camera's frames: track, decide stillness, publish."""

    def __init__(self, node: TrackerNode, model: CameraModel, yaw_rad: float) -> None:
        self.node = node
        self.name = model.name
        self.model = model
        self.size: tuple[int, int] | None = None
        self.handled_ns = -1
        self.stillness = StillnessRule(node.still_frames, 0.0)
        self.tracker = FrameTracker(yaw_rad)
        self.capture_pub = node.create_publisher(PoseStamped, CAPTURE_TOPICS[self.name],
                                                 CAPTURE_QOS)
        self.covariance_pub = node.create_publisher(
            PoseWithCovarianceStamped, CAPTURE_COVARIANCE_TOPICS[self.name], CAPTURE_QOS)
        self.status_pub = node.create_publisher(DiagnosticStatus,
                                                f'/camera/{self.name}/tracker_status',
                                                latched(1))
        self._said: str | None = None

    def on_info(self, msg: CameraInfo) -> None:
        self.size = (int(msg.width), int(msg.height))

    def _say(self, level: bytes, message: str) -> None:
        if message != self._said:
            self._said = message
            self.status_pub.publish(DiagnosticStatus(level=level, name=f'tracker {self.name}',
                                                     message=message))

    def camera(self, width: int, height: int) -> CameraModel:
        """The camera as this frame shows it: its resolution comes with the image."""
        return dataclasses.replace(self.model, resolution_px=(width, height))

    def on_image(self, data: bytes) -> None:
        try:
            msg = read_image(data)
        except CameraConfigError as error:
            self._refuse(error)   # no stamp to report it under: as a frame lost on the way
            return
        found, capture = self._see(msg)
        self.node.on_frame(self, stamp_ns(msg.header.stamp), found, capture)

    def _refuse(self, error: CameraConfigError) -> None:
        self.node.get_logger().warning(f'{self.name}: frame refused: {error}')
        self._say(DiagnosticStatus.ERROR, f'frame refused: {error}')
        self.stillness.reset()
        self.tracker.reset()

    def _see(self, msg: ImageLike) -> tuple[bool, _Capture | None]:
        """Track one frame: whether the fiducial is in it, and the capture it gives, if any."""
        try:
            pixels = image_array(msg, self.size)
        except CameraConfigError as error:
            self._refuse(error)
            return False, None
        camera = self.camera(msg.width, msg.height)
        result = self.tracker(pixels, camera)
        if result.pose is None:
            self.stillness.reset()
            self._say(DiagnosticStatus.WARN, result.reason)
            return False, None
        x, y, phi = result.pose
        self.stillness.tolerance_m = self.node.still_px * min(camera.pixel_size_m)
        if not self.stillness.still(x, y):
            self._say(DiagnosticStatus.OK, 'moving')
            return True, None
        self._say(DiagnosticStatus.OK, 'still: capturing')
        capture = PoseStamped()
        capture.header.stamp = msg.header.stamp
        capture.header.frame_id = self.node.frame_id
        capture.pose.position.x, capture.pose.position.y = x, y
        capture.pose.orientation.z, capture.pose.orientation.w = yaw_to_quaternion(phi)
        covariance = PoseWithCovarianceStamped()
        covariance.header = capture.header
        covariance.pose.pose = capture.pose
        covariance.pose.covariance = camera.uncertainty(phi).covariance()
        return True, (self, covariance, capture)


# A capture as the tracker holds it until the arbiter lets it go: its camera, then both messages.
_Capture = tuple[_CameraReader, PoseWithCovarianceStamped, PoseStamped]


COMPONENT = NodeComponent(TrackerNode, config_errors=(CameraConfigError,))


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
