"""ROS 2 adapter of the tracker: camera images in, pose captures out (the camera contract).

Subscribes, per camera (``cameras``: macro, micro), a sensor_msgs/Image and its CameraInfo
(``<name>.image_topic``, ``<name>.info_topic``: remap them to a real driver's) and publishes, in
the ``platform`` frame:
  /camera/<name>/pose                    geometry_msgs/PoseStamped captures, stamped with the frame
  /camera/<name>/pose_with_covariance    the same, with the covariance of vision_node's camera
                                         model (``<name>.noise_px``, ``<name>.quantisation_px``)
  /camera/<name>/pose_in_motion          with ``captures_in_motion``: each frame of the moving
                                         robot (PoseWithCovarianceStamped), stamped at its
                                         exposure's middle (``<name>.motion.*``), its covariance
                                         grown by the blur (:mod:`.motion_capture`); from the
                                         finest camera that captures it in motion, as the
                                         model vision has it
  /camera/<name>/tracker_status          diagnostic_msgs/DiagnosticStatus: why a frame gave no
                                         pose (fiducial not found, cut by the edge, ambiguous) or
                                         why it was refused (encoding, size), on each change
  /lockstep                              after each frame: up to which stamp every camera's
                                         frames are handled, and the captures (and captures in
                                         motion) that caused
A capture is published only while the robot is still, decided from the images alone: the
fiducial's pose in the last ``still_frames`` frames agrees within ``still_tolerance_px`` pixels;
and only from the finest camera that sees the robot (:mod:`omni_micro_vision.tracking`).
Where each camera's pixels lie on the platform is its calibration (``<name>.calibration.*``,
written by ``omni-micro calibrate-camera``) or, without one, its nominal geometry
(``<name>.center_m``, ``field_m``, ``resolution_px``, ``yaw_rad``, ``mirrored``):
:mod:`omni_micro_vision.tracked_camera`. Frames in any common encoding are read
(:mod:`omni_micro_vision.encodings`), best effort by default (``image_reliability``), and
refused, with the reason in ``tracker_status``, when their size or their CameraInfo
contradicts that geometry. The image processing is :mod:`omni_micro_vision.tracking`'s.
It reads images only once its capture writers have matched the readers of the nodes named in
``capture_readers`` (bare captures), ``covariance_readers`` and ``motion_readers`` (captures
in motion; all empty when started alone), so that none of them misses the first captures.

Several robots under one camera pair (a fleet, ``robots``: their namespaces, robot_k
carrying fiducial code k): each frame's robots are named by their codes
(:mod:`omni_micro_vision.code_reading`) and each named robot's captures published under its
namespace, ``/robot_k/camera/<name>/pose`` and ``pose_with_covariance``, and with
``captures_in_motion`` each moving robot's ``/robot_k/camera/<name>/pose_in_motion``
(:mod:`omni_micro_vision.fleet_tracking`); a robot a frame cannot name gives no capture and is
said in ``tracker_status`` (why, and where) and, once per reason, in the log.
"""

from __future__ import annotations

import math
from typing import Any

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rclpy.validate_topic_name import validate_topic_name
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_common.conventions import PLATFORM_FRAME, join_stamp, stamp_ns
from omni_micro_common.lockstep import Ack
from omni_micro_common.lockstep_groups import nodes_of_robot, qualified_node_name
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.qos import CAPTURE_QOS, IMAGE_QOS, camera_info_profile
from omni_micro_common.reader_matching import (
    capture_reader_names,
    node_list_parameter,
    when_capture_readers_matched,
    when_readers_matched,
)
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
)
from omni_micro_vision.camera import checked_cameras
from omni_micro_vision.capture_messages import capture_pose, with_uncertainty
from omni_micro_vision.code_reading import Sighting
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fleet_tracking import FleetCaptures, RobotCapture, robot_codes
from omni_micro_vision.rendering import Sensor
from omni_micro_vision.tracked_camera import tracked_camera
from omni_micro_vision.tracker_reader import CameraReader, HeldCapture, HeldInMotion
from omni_micro_vision.tracking import CameraArbiter

RELIABILITIES = {'reliable': ReliabilityPolicy.RELIABLE,
                 'best_effort': ReliabilityPolicy.BEST_EFFORT}



def checked_topic(name: str, topic: object) -> str:
    """A topic name parameter, checked now (rclpy would raise only once it subscribes)."""
    try:
        validate_topic_name(str(topic))
    except InvalidTopicNameException as error:
        raise CameraConfigError(f'{name}: {str(error).splitlines()[0]} {topic!r}') from None
    return str(topic)


class TrackerNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options (context, parameter_overrides, ...) as rclpy's Node takes them: tests
        # build the node in-process with them.
        super().__init__('tracker_node', **node_options)
        self.frame_id = self.declare_parameter('frame_id', PLATFORM_FRAME).value
        # An empty list reaches rclpy as no value at all.
        cameras = list(self.declare_parameter('cameras', ['macro', 'micro']).value or [])
        self.still_frames = int(self.declare_parameter('still_frames', 3).value)
        self.still_px = float(self.declare_parameter('still_tolerance_px', 0.2).value)
        if self.still_frames < 2 or not self.still_px > 0:
            raise CameraConfigError(f'still_frames must be >= 2 and still_tolerance_px > 0, got '
                                    f'{self.still_frames} and {self.still_px}')
        checked_cameras(cameras)
        self.captures_in_motion = bool(self.declare_parameter('captures_in_motion', False).value)
        self.robots = robot_codes(node_list_parameter(self, 'robots'))
        # Best effort by default, which meets a reliable and a best-effort driver alike
        # (REP-2003); the lockstep graph asks reliable of its own camera_node.
        self.reliability = self.declare_parameter('image_reliability', 'best_effort').value
        if self.reliability not in RELIABILITIES:
            raise CameraConfigError(f'image_reliability must be one of {sorted(RELIABILITIES)}, '
                                    f'got {self.reliability!r}')
        image_qos = QoSProfile(depth=IMAGE_QOS.depth,
                               reliability=RELIABILITIES[self.reliability])
        self.lockstep = LockstepReporter(self)
        self.readers: list[CameraReader] = []
        inputs: list[tuple[str, str, CameraReader]] = []
        fields: dict[str, float] = {}
        # Every camera's parameters are declared (one params file serves any choice of cameras);
        # only those in ``cameras`` are read.
        for name in CAPTURE_TOPICS:
            image_topic = checked_topic(f'{name}.image_topic', self.declare_parameter(
                f'{name}.image_topic', f'/camera/{name}/image_raw').value)
            info_topic = checked_topic(f'{name}.info_topic', self.declare_parameter(
                f'{name}.info_topic', f'/camera/{name}/camera_info').value)
            # Checks the parameters now, whichever cameras are used.
            camera = tracked_camera(name, self._setting)
            # A driver's frame is stamped at its exposure's start (camera_node's, and most
            # drivers' trigger time); the blur spans exposure_s.
            exposure = float(self.declare_parameter(f'{name}.motion.exposure_s',
                                                    Sensor.exposure_s).value)
            after_stamp = float(self.declare_parameter(
                f'{name}.motion.mid_exposure_after_stamp_s', 0.5 * Sensor.exposure_s).value)
            if not (math.isfinite(exposure) and exposure >= 0.0
                    and math.isfinite(after_stamp) and after_stamp >= 0.0):
                raise CameraConfigError(f'{name}.motion.exposure_s and '
                                        f'{name}.motion.mid_exposure_after_stamp_s must be '
                                        f'finite numbers >= 0, got {exposure!r} and '
                                        f'{after_stamp!r}')
            if name not in cameras:
                continue
            reader = CameraReader(self, camera, exposure, after_stamp, image_topic)
            self.readers.append(reader)
            fields[name] = min(camera.model.field_m)
            inputs.append((image_topic, info_topic, reader))
            columns, rows = camera.plane.resolution_px
            self.get_logger().info(
                f'{name}: {columns} x {rows} pixels mapped by '
                + (f'its calibration (residual {camera.plane.residual_px:.3g} px, '
                   f'{camera.plane.residual_m * 1e6:.3g} um)' if camera.calibrated else
                   'the nominal geometry (no calibration: a real camera needs omni-micro '
                   'calibrate-camera)'))
        # The smaller field has the finer pixel.
        self.arbiter: CameraArbiter[HeldCapture] = CameraArbiter(
            sorted(fields, key=fields.__getitem__))
        # The same for the captures in motion: one capture per frame time, whose stamp then says
        # which have been handled (omni_micro_common.lockstep).
        self.motion_arbiter: CameraArbiter[HeldInMotion] = CameraArbiter(
            sorted(fields, key=fields.__getitem__))
        self.fleet: FleetCaptures[HeldInMotion] | None = FleetCaptures(
            sorted(fields, key=fields.__getitem__), list(self.robots.values()),
            self.still_frames, {r.name: r.stillness.tolerance_m for r in self.readers},
            self._robot_in_motion if self.captures_in_motion else None) \
            if self.robots else None
        # Each robot's captures, per camera: (bare, with covariance) under its namespace.
        self.robot_publishers = {
            (code, reader.name): (
                self.create_publisher(PoseStamped, f'/{robot}{CAPTURE_TOPICS[reader.name]}',
                                      CAPTURE_QOS),
                self.create_publisher(PoseWithCovarianceStamped,
                                      f'/{robot}{CAPTURE_COVARIANCE_TOPICS[reader.name]}',
                                      CAPTURE_QOS))
            for robot, code in self.robots.items() for reader in self.readers}
        self.robot_in_motion_publishers = {
            (code, reader.name): self.create_publisher(
                PoseWithCovarianceStamped, f'/{robot}{CAPTURE_IN_MOTION_TOPICS[reader.name]}',
                CAPTURE_QOS)
            for robot, code in self.robots.items() for reader in self.readers
            if self.captures_in_motion}

        def read_images() -> None:
            for image_topic, info_topic, reader in inputs:
                # Raw: the pixels are read where they lie (image_messages.read_image).
                self.create_subscription(Image, image_topic, reader.on_image, image_qos,
                                         raw=True, event_callbacks=reader.events(image_topic))
                self.create_subscription(CameraInfo, info_topic, reader.on_info,
                                         camera_info_profile(image_qos),
                                         event_callbacks=reader.events(info_topic))

        # Each robot's lockstep gate hears of its own captures (robot 1's controller never
        # handles robot 0's), as ``robot_k/tracker_node``.
        self.robot_lockstep = {code: LockstepReporter(self, qualified_node_name(robot,
                                                                               self.get_name()))
                               for robot, code in self.robots.items()}
        # The nodes that must not miss a capture, by the topics they read (empty when started
        # alone): the images are read, and the camera (whose frames wait for these readers),
        # then the robot's clock, start only once the capture writers have matched them. A
        # robot's publishers wait for the readers in its namespace and for those outside every
        # robot's (a recorder's).
        if self.robots:
            names = capture_reader_names(self)
            when_readers_matched(self, [
                (publisher, nodes_of_robot(robot, readers))
                for robot, code in self.robots.items() for reader in self.readers
                for publisher, readers in zip(
                    (*self.robot_publishers[code, reader.name],
                     self.robot_in_motion_publishers.get((code, reader.name))), names,
                    strict=True) if publisher is not None],
                read_images)
        else:
            when_capture_readers_matched(
                self, [reader.capture_pub for reader in self.readers],
                [reader.covariance_pub for reader in self.readers],
                [reader.in_motion_pub for reader in self.readers
                 if reader.in_motion_pub is not None], read_images)
        self.get_logger().info(f'tracking {", ".join(cameras)}; a capture once '
                               f'{self.still_frames} frames agree within {self.still_px} px')

    def _setting(self, name: str, default: object) -> object:
        """A camera setting as a declared parameter (tracked_camera reads them all so). One
        with no default (a calibration's entries) takes whatever type a params file gives:
        tracked_camera checks it and names it."""
        if default is None:
            return self.declare_parameter(
                name, None, ParameterDescriptor(dynamic_typing=True)).value
        return self.declare_parameter(name, default).value

    def _robot_in_motion(self, camera: str, stamp: int, pose: tuple[float, float, float],
                         last: tuple[int, float, float]) -> HeldInMotion | None:
        """A fleet robot's capture in motion, as one robot's (CameraReader.in_motion)."""
        reader = next(r for r in self.readers if r.name == camera)
        return reader.in_motion(join_stamp(*divmod(stamp, 1_000_000_000)), pose,
                                (join_stamp(*divmod(last[0], 1_000_000_000)), *last[1:]))

    def on_fleet_frame(self, reader: CameraReader, stamp: int,
                       sightings: list[Sighting]) -> None:
        """A frame of several robots: each named robot's due captures (and captures in motion)
        published under its namespace, the robots the frame could not name said, then the
        report."""
        assert self.fleet is not None
        reader.handled_ns = max(reader.handled_ns, stamp)
        frame = self.fleet.on_frame(reader.name, stamp, sightings)
        for capture in frame.captures:
            self._publish_robot_capture(capture)
        moving: dict[int, list[int]] = {}
        for robot, (owner, message) in frame.in_motion:
            self.robot_in_motion_publishers[robot, owner.name].publish(message)
            moving.setdefault(robot, []).append(stamp_ns(message.header.stamp))
        reader.say_sightings(sightings, frame.unnamed)
        handled_ns = min(r.handled_ns for r in self.readers)
        for code, lockstep in self.robot_lockstep.items():
            own = [capture.stamp_ns for capture in frame.captures if capture.robot == code]
            in_motion = moving.get(code)
            lockstep.report(Ack(lockstep.name, None,
                                captures_ns=(own[0], own[-1]) if own else None,
                                frame_handled_ns=handled_ns,
                                motion_ns=(in_motion[0], in_motion[-1]) if in_motion else None))

    def _publish_robot_capture(self, capture: RobotCapture) -> None:
        reader = next(r for r in self.readers if r.name == capture.camera)
        bare, with_covariance = self.robot_publishers[capture.robot, capture.camera]
        x, y, phi = capture.pose
        pose = capture_pose(*divmod(capture.stamp_ns, 1_000_000_000), self.frame_id, x, y, phi)
        # The uncertainty first, as vision_node: a reader of the bare capture has it by then.
        with_covariance.publish(with_uncertainty(pose, reader.camera.uncertainty(phi)))
        bare.publish(pose)

    def on_frame(self, reader: CameraReader, stamp: int, found: bool,
                 capture: HeldCapture | None, in_motion: HeldInMotion | None = None) -> None:
        """Publish what is due, then report: every camera's frames are handled up to the oldest
        of their latest (a capture from a frame still on its way could come later)."""
        reader.handled_ns = max(reader.handled_ns, stamp)
        due = self.arbiter.on_frame(reader.name, stamp, found, capture)
        for _, (owner, covariance, pose) in due:
            # The uncertainty first, as vision_node: a reader of the bare capture has it by then.
            owner.covariance_pub.publish(covariance)
            owner.capture_pub.publish(pose)
        # A finer camera that found the robot but lost it to the blur leaves it to the coarser.
        moving = [message for _, (owner, message) in
                  self.motion_arbiter.on_frame(reader.name, stamp, in_motion is not None,
                                               in_motion)
                  if owner.publish_in_motion(message)]
        self.lockstep.report(Ack(
            self.get_name(), None, captures_ns=(due[0][0], due[-1][0]) if due else None,
            frame_handled_ns=min(r.handled_ns for r in self.readers),
            motion_ns=(stamp_ns(moving[0].header.stamp), stamp_ns(moving[-1].header.stamp))
            if moving else None))


def say_frames(node: TrackerNode) -> None:
    """Its last words: each camera's frames, those that came of those the driver sent."""
    for reader in node.readers:
        if reader.losses.sent_total:
            print(reader.losses.summary(), flush=True)


COMPONENT = NodeComponent(TrackerNode, config_errors=(CameraConfigError,),
                          on_shutdown=say_frames)


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
