"""ROS 2 adapter of the overhead cameras.

Subscribes /odom (the robot's true motion, from the dynamics node) and publishes, while the robot
is still, geometry_msgs/PoseStamped captures in the ``platform`` frame:
  /camera/macro/pose   captures of the macro camera (15 cm x 15 cm field)
  /camera/micro/pose   captures of the micro camera (2 mm x 2 mm field)
  /camera/<name>/pose_with_covariance   each capture again, same stamp, with its uncertainty
                       (geometry_msgs/PoseWithCovarianceStamped, from the camera model)
  /camera/<name>/pose_in_motion   with ``captures_in_motion``: captures of the moving
                       robot (PoseWithCovarianceStamped), at each camera's
                       ``<name>.motion.frame_rate_hz``, stamped at mid-exposure, published once
                       simulated time has reached the capture's delay
                       (:mod:`omni_micro_vision.motion_capture`)
  /camera/status       diagnostic_msgs/DiagnosticStatus: which camera sees the robot, or a
                       warning when none does
  /lockstep            its report after each odometry sample (omni_micro_common.lockstep),
                       with the stamps of the captures and captures in motion it published
It reads /odom only once its capture writers have matched the readers of the nodes named in
``capture_readers`` (bare captures), ``covariance_readers`` and ``motion_readers`` (captures
in motion; all empty when started alone), so that none of them misses the first captures.
The stamp of a capture is its exposure time in simulated time. The camera model and the capture
rule are in :mod:`omni_micro_vision.camera`; this node only moves numbers in and out.
"""

from __future__ import annotations

import math
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from omni_micro_common.conventions import (
    PLATFORM_FRAME,
    STATUS_TIME_KEY,
    join_stamp,
    quaternion_to_yaw,
    split_stamp,
    stamp_ns,
)
from omni_micro_common.lockstep import Ack
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.publication_counts import PublicationCounter
from omni_micro_common.qos import CAPTURE_QOS, DATA_QOS, PER_TICK_SUBSCRIPTION_EVENTS, latched
from omni_micro_common.reader_matching import (
    node_list_parameter,
    when_capture_readers_matched,
)
from omni_micro_common.tick_messages import robot_odometry_template
from omni_micro_common.topic_names import (
    CAMERA_STATUS_TOPIC,
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    ODOM_TOPIC,
)
from omni_micro_vision.camera import (
    DEFAULT_RIG,
    CameraFaults,
    CameraModel,
    CameraRig,
    Capture,
    CaptureRule,
    FaultInjector,
    StationaryCamera,
)
from omni_micro_vision.capture_messages import capture_pose, with_uncertainty
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.motion_capture import CameraTiming, MotionCapture, MovingCamera

# Latched: a subscriber that comes later still learns which camera is in use.
CAMERA_STATUS_QOS = latched(1)


class VisionNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options (context, parameter_overrides, ...) as rclpy's Node takes them: tests
        # build the node in-process with them.
        super().__init__('vision_node', **node_options)
        rule_defaults = CaptureRule()
        self.frame_id = self.declare_parameter('frame_id', PLATFORM_FRAME).value
        seed = self.declare_parameter('seed', 0).value
        rule = CaptureRule(**{
            name: self.declare_parameter(name, getattr(rule_defaults, name)).value
            for name in ('speed_threshold_m_s', 'angular_threshold_rad_s', 'dwell_s',
                         'frame_rate_hz')})
        baseline = self.declare_parameter('marker_baseline_m',
                                          DEFAULT_RIG.macro.marker_baseline_m).value
        cameras = {}
        for name in ('macro', 'micro'):
            default: CameraModel = getattr(DEFAULT_RIG, name)
            cameras[name] = CameraModel(
                name,
                self.declare_parameter(f'{name}.center_m', list(default.center_m)).value,
                self.declare_parameter(f'{name}.field_m', list(default.field_m)).value,
                self.declare_parameter(f'{name}.resolution_px',
                                       [int(v) for v in default.resolution_px]).value,
                self.declare_parameter(f'{name}.noise_px', default.noise_px).value,
                self.declare_parameter(f'{name}.quantisation_px', default.quantisation_px).value,
                baseline)
        self.camera = StationaryCamera(CameraRig(**cameras), rule, seed)
        self.moving = self._declare_moving_camera(CameraRig(**cameras), seed)
        fault_defaults = CameraFaults()
        faults = CameraFaults(**{
            name: self.declare_parameter(f'faults.{name}', getattr(fault_defaults, name)).value
            for name in CameraFaults.__dataclass_fields__})
        self.faults = FaultInjector(faults, seed)
        if faults != fault_defaults:
            self.get_logger().warning(f'camera faults injected: {faults}')
        self.publication_counter = PublicationCounter()
        count = self.publication_counter.wrap
        self.capture_pubs = {name: count(self.create_publisher(PoseStamped, topic, CAPTURE_QOS))
                             for name, topic in CAPTURE_TOPICS.items()}
        self.covariance_pubs = {
            name: count(self.create_publisher(PoseWithCovarianceStamped, topic, CAPTURE_QOS))
            for name, topic in CAPTURE_COVARIANCE_TOPICS.items()}
        self.in_motion_pubs = {
            name: count(self.create_publisher(PoseWithCovarianceStamped, topic, CAPTURE_QOS))
            for name, topic in CAPTURE_IN_MOTION_TOPICS.items()} if self.moving else {}
        self.status_pub = count(self.create_publisher(DiagnosticStatus, CAMERA_STATUS_TOPIC,
                                                      CAMERA_STATUS_QOS))
        self.lockstep = LockstepReporter(self)
        # Raw, read in place: an Odometry's conversion to Python cost more than the cameras.
        self._odometry = robot_odometry_template(self.get_namespace().strip('/'))
        self._status: tuple[int, str] | None = None
        # The nodes that must not miss a capture, by the topics they read, or a status
        # (``status_readers``; all empty when started alone): the first status is said, and
        # /odom read (the robot's clock, which waits for that reader, starts), only once those
        # writers have matched their readers. The first captures come at time 0, and one was
        # lost to markers_node in a fast start; the first status, latched with depth 1 and said
        # before, was lost to a fleet's recorder whose reader this writer matched only after
        # the next status (at 0.04 s) had replaced it.
        when_capture_readers_matched(
            self, self.capture_pubs.values(), self.covariance_pubs.values(),
            self.in_motion_pubs.values(), self._read_odometry,
            others=[(self.status_pub, node_list_parameter(self, 'status_readers'))])
        # Last: from here on only faults.* may change (the parameters above are declared).
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.get_logger().info(
            f'cameras ready: macro pixel {cameras["macro"].pixel_size_m[0] * 1e6:.1f} um, '
            f'micro pixel {cameras["micro"].pixel_size_m[0] * 1e6:.3f} um, seed {seed}')

    def _declare_moving_camera(self, rig: CameraRig, seed: int) -> MovingCamera | None:
        """Captures in motion (off by default): each camera's rate, exposure, delay and jitter."""
        enabled = bool(self.declare_parameter('captures_in_motion', False).value)
        defaults = CameraTiming()
        timings = {name: CameraTiming(**{
            field: self.declare_parameter(f'{name}.motion.{field}', getattr(defaults, field)).value
            for field in CameraTiming.__dataclass_fields__}) for name in CAPTURE_TOPICS}
        return MovingCamera(rig, timings, seed) if enabled else None

    def _read_odometry(self) -> None:
        """Its first status, then /odom: once its writers have matched their readers."""
        self._publish_status(DiagnosticStatus.OK, 'waiting for the robot to stop', at_s=0.0)
        self.create_subscription(Odometry, ODOM_TOPIC, self._on_odometry, DATA_QOS, raw=True,
                                 event_callbacks=PER_TICK_SUBSCRIPTION_EVENTS)

    def _on_set_parameters(self, params: list) -> SetParametersResult:
        """Only the fault injection may change at run time; it is checked before it applies."""
        changes = {}
        for param in params:
            if not param.name.startswith('faults.'):
                return SetParametersResult(
                    successful=False, reason=f'{param.name} is fixed while the node runs; '
                                             f'only faults.* can change')
            changes[param.name.removeprefix('faults.')] = param.value
        if not changes:
            return SetParametersResult(successful=True)
        current = self.faults.faults
        try:
            faults = CameraFaults(**{**current.__dict__, **changes})
        except (CameraConfigError, TypeError) as error:
            return SetParametersResult(successful=False, reason=str(error))
        self.faults.faults = faults
        self.get_logger().warning(f'camera faults now: {faults}')
        return SetParametersResult(successful=True)

    def _publish_status(self, level: int, message: str, at_s: float, **values: str) -> None:
        """``at_s``: the simulated time of the sample or capture it is about (STATUS_TIME_KEY)."""
        if self._status == (level, message):
            return
        self._status = (level, message)
        status = DiagnosticStatus(level=level, name='omni_micro_vision', message=message,
                                  hardware_id='overhead_cameras')
        values = {STATUS_TIME_KEY: repr(float(at_s)), **values}
        status.values = [KeyValue(key=key, value=value) for key, value in values.items()]
        self.status_pub.publish(status)

    def _on_odometry(self, data: bytes) -> None:
        sec, nanosec, *values = self._odometry.decode(data)
        published, in_motion = self._see(int(sec), int(nanosec), values)
        # Last: everything this sample caused is out before the robot may move on.
        self.lockstep.report(Ack(
            self.get_name(), int(sec) * 1_000_000_000 + int(nanosec),
            captures_ns=(min(published), max(published)) if published else None,
            motion_ns=(min(in_motion), max(in_motion)) if in_motion else None))

    def _see(self, sec: int, nanosec: int, values: list[float]) -> tuple[list[int], list[int]]:
        """Feed one sample (x, y, qz, qw, vx, vy, wz as ODOMETRY_FIELDS orders them) to the
        cameras; returns the stamps (ns) of the captures and captures in motion published."""
        if not all(math.isfinite(v) for v in values):
            self.get_logger().error(f'ignored odometry with a non-finite value: {tuple(values)}')
            return [], []
        x, y, qz, qw, vx, vy, wz = values
        phi = quaternion_to_yaw(qz, qw)
        events = self.camera.on_odometry(join_stamp(sec, nanosec), x, y, phi,
                                         math.hypot(vx, vy), wz)
        in_motion = []
        if self.moving is not None:
            # The twist is in the robot's frame (REP-105): the cameras see it on the platform.
            cos, sin = math.cos(phi), math.sin(phi)
            in_motion = [self._publish_in_motion(moving) for moving in self.moving.on_odometry(
                join_stamp(sec, nanosec), x, y, phi, cos * vx - sin * vy, sin * vx + cos * vy)]
        for event in events:
            if isinstance(event, Capture):
                self.faults.submit(event)
            else:
                self._publish_status(DiagnosticStatus.WARN, 'robot outside the macro field',
                                     at_s=join_stamp(sec, nanosec), x_m=repr(x), y_m=repr(y))
                self.get_logger().warning(
                    f'robot at ({x * 1e3:.3f}, {y * 1e3:.3f}) mm '
                    f'is outside the macro field: no capture', throttle_duration_sec=5.0)
        return [self._publish_capture(capture) for capture in
                self.faults.due(join_stamp(sec, nanosec))], in_motion

    def _publish_capture(self, capture: Capture) -> int:
        """Publish one capture; returns its stamp in nanoseconds."""
        msg = capture_pose(*split_stamp(capture.stamp_s), self.frame_id, capture.x_m,
                           capture.y_m, capture.phi_rad)
        # The uncertainty first: a controller reading it has the whole capture when the
        # PoseStamped arrives, and the lockstep report comes after both.
        self.covariance_pubs[capture.camera].publish(with_uncertainty(msg, capture.uncertainty))
        self.capture_pubs[capture.camera].publish(msg)
        self._publish_status(DiagnosticStatus.OK, f'{capture.camera} camera',
                             at_s=capture.stamp_s, camera=capture.camera)
        return stamp_ns(msg.header.stamp)

    def _publish_in_motion(self, capture: MotionCapture) -> int:
        """Publish one capture in motion; returns its stamp in nanoseconds."""
        pose = capture_pose(*split_stamp(capture.stamp_s), self.frame_id, capture.x_m,
                            capture.y_m, capture.phi_rad)
        self.in_motion_pubs[capture.camera].publish(with_uncertainty(pose, capture.uncertainty))
        return stamp_ns(pose.header.stamp)


COMPONENT = NodeComponent(VisionNode, config_errors=(CameraConfigError,))


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
