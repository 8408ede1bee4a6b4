"""One camera's frames in ``tracker_node``: checked against the camera's geometry, tracked,
turned into captures when the robot is still (and captures in motion), and its status said.
The node (:mod:`omni_micro_vision.tracker_node`) holds the readers and arbitrates between them.
"""

from __future__ import annotations

import math
import time
from typing import Any, Protocol

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rclpy.event_handler import QoSRequestedIncompatibleQoSInfo, SubscriptionEventCallbacks
from rclpy.qos import QoSPolicyKind
from sensor_msgs.msg import CameraInfo

from omni_micro_common.conventions import (
    FRAMES_LOST_CAUSE_KEY,
    FRAMES_LOST_KEY,
    FRAMES_LOST_SINCE_KEY,
    FRAMES_LOST_TOTAL_KEY,
    FRAMES_SENT_KEY,
    FRAMES_SENT_TOTAL_KEY,
    join_stamp,
    split_stamp,
    stamp_ns,
)
from omni_micro_common.installed import dds_profile_to_export
from omni_micro_common.qos import CAPTURE_QOS, IMAGE_QOS, latched
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    TRACKER_STATUS_TOPICS,
    robot_name,
)
from omni_micro_vision.capture_messages import capture_pose, with_uncertainty
from omni_micro_vision.code_reading import Sighting, identify
from omni_micro_vision.encodings import full_scale
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fleet_tracking import FleetCaptures
from omni_micro_vision.frame_ages import FrameAges
from omni_micro_vision.frame_losses import FrameLosses, LossStretch, likely_cause
from omni_micro_vision.image_messages import ImageLike, image_array, read_image
from omni_micro_vision.motion_capture import trackable, uncertainty_in_motion
from omni_micro_vision.tracked_camera import TrackedCamera
from omni_micro_vision.tracking import FrameTracker, StillnessRule


class TrackerHost(Protocol):
    """What a camera's reader needs of the node holding it (tracker_node's ``TrackerNode``):
    its settings, a publisher and a logger of its own, and where each frame goes once read."""

    frame_id: str
    still_frames: int
    still_px: float
    captures_in_motion: bool
    reliability: str
    robots: dict[str, int]
    fleet: FleetCaptures[Any] | None

    def create_publisher(self, msg_type: Any, topic: str, qos: Any) -> Any: ...

    def get_logger(self) -> Any: ...

    def on_frame(self, reader: CameraReader, stamp: int, found: bool,
                 capture: HeldCapture | None, in_motion: HeldInMotion | None = None) -> None: ...

    def on_fleet_frame(self, reader: CameraReader, stamp: int,
                       sightings: list[Sighting]) -> None: ...


class CameraReader:
    """One camera's frames: check them against the camera's geometry, track, decide stillness,
    publish."""

    def __init__(self, node: TrackerHost, camera: TrackedCamera, exposure_s: float,
                 mid_exposure_after_stamp_s: float, image_topic: str) -> None:
        self.node = node
        self.image_topic = image_topic
        # A driver's frames (wall-clock stamps): how old they come, said in the status.
        self.ages = FrameAges(mid_exposure_after_stamp_s)
        self._age_values: list[KeyValue] = []
        # Frames the driver sent that never came (frame_losses), said once per stretch.
        self.losses = FrameLosses(camera.plane.name, image_topic)
        self._loss_values: list[KeyValue] = []
        self._tracking_s = 0.0   # the longest this node took over a frame lately
        self._frame_bytes = 0
        self.camera = camera
        self.exposure_s = exposure_s
        self.mid_exposure_after_stamp_s = mid_exposure_after_stamp_s
        # The last pose found, and when: the robot's velocity over a frame, for the blur.
        self._last_seen: tuple[float, float, float] | None = None
        self.name = camera.plane.name
        self.handled_ns = -1
        # Why the latest CameraInfo rules its frames out (None: it does not, or none came yet).
        self.info_refusal: str | None = None
        self.stillness = StillnessRule(node.still_frames,
                                       node.still_px * min(camera.plane.pixel_size_m))
        self.tracker = FrameTracker(camera.plane, camera.bit_depth)
        self.capture_pub = node.create_publisher(PoseStamped, CAPTURE_TOPICS[self.name],
                                                 CAPTURE_QOS)
        self.covariance_pub = node.create_publisher(
            PoseWithCovarianceStamped, CAPTURE_COVARIANCE_TOPICS[self.name], CAPTURE_QOS)
        self.status_pub = node.create_publisher(DiagnosticStatus,
                                                TRACKER_STATUS_TOPICS[self.name], latched(1))
        self.in_motion_pub = node.create_publisher(
            PoseWithCovarianceStamped, CAPTURE_IN_MOTION_TOPICS[self.name],
            CAPTURE_QOS) if node.captures_in_motion and not node.robots else None
        self._said: str | None = None
        self._said_level = DiagnosticStatus.OK
        # Several robots: the sensor's full scale over the frames so far, the reasons logged.
        self._full_scale = 0
        self._unnamed_said: set[str] = set()

    def events(self, topic: str) -> SubscriptionEventCallbacks:
        """rclpy's incompatible-QoS event, said by this node in its status and log."""
        def on_incompatible(event: QoSRequestedIncompatibleQoSInfo) -> None:
            policy = QoSPolicyKind(event.last_policy_kind).name.lower()
            hint = ('set image_reliability: best_effort (it meets reliable and best-effort '
                    'drivers)' if policy == 'reliability' else
                    f"make the driver's {policy} QoS match a volatile reader")
            message = (f'{topic}: a publisher offers QoS incompatible with this reader '
                       f'({policy}; image_reliability is {self.node.reliability}): {hint}')
            self.node.get_logger().warning(message)
            self._say(DiagnosticStatus.ERROR, message)
        return SubscriptionEventCallbacks(incompatible_qos=on_incompatible)

    def on_info(self, msg: CameraInfo) -> None:
        self.losses.add_info(stamp_ns(msg.header.stamp))
        refusal = self.camera.refusal(int(msg.width), int(msg.height), list(msg.k), list(msg.d))
        if refusal != self.info_refusal and refusal is not None:
            self.node.get_logger().warning(f'{self.name}: frames refused: {refusal}')
        self.info_refusal = refusal

    def _say(self, level: bytes, message: str, again: bool = False) -> None:
        """A status on each change (``again``: even without one, with new ages); it carries the
        frames' ages once they are measured (frame_ages)."""
        if message != self._said or again:
            self._said, self._said_level = message, level
            self.status_pub.publish(DiagnosticStatus(level=level, name=f'tracker {self.name}',
                                                     message=message, values=self._values))

    @property
    def _values(self) -> list[KeyValue]:
        """What a status carries: the frames' ages, the latest stretch of lost frames, and
        all lost of all sent so far (as they stand when it is said)."""
        totals = [KeyValue(key=FRAMES_LOST_TOTAL_KEY, value=str(self.losses.lost_total)),
                  KeyValue(key=FRAMES_SENT_TOTAL_KEY, value=str(self.losses.sent_total))]
        return self._age_values + self._loss_values + (totals if self.losses.lost_total else [])

    def on_image(self, data: bytes) -> None:
        arrived_ns = time.time_ns()
        try:
            msg = read_image(data)
        except CameraConfigError as error:
            self._refuse(error)   # no stamp to report it under: as a frame lost on the way
            return
        stamp = stamp_ns(msg.header.stamp)
        if self.node.fleet is not None:
            sightings = self._identify(msg)
            if sightings is not None:
                self.node.on_fleet_frame(self, stamp, sightings)
        else:
            found, capture, in_motion = self._see(msg)
            self.node.on_frame(self, stamp, found, capture, in_motion)
        done_ns = time.time_ns()
        # Decays, so that one slow frame (the first, compiling) is not blamed for ever.
        self._tracking_s = max((done_ns - arrived_ns) * 1e-9, 0.9 * self._tracking_s)
        self._frame_bytes = len(data)
        stretch = self.losses.add(stamp, self._loss_cause)
        if stretch is not None:
            self._state_losses(stretch)
        if self.ages.add(stamp, arrived_ns, done_ns):
            self._state_ages()

    def _loss_cause(self) -> str:
        period_ns = self.losses.period_ns
        return likely_cause(self._frame_bytes, self.node.reliability == 'best_effort',
                            self._tracking_s, (period_ns or 0.0) * 1e-9,
                            dds_profile_to_export(), IMAGE_QOS.depth)

    def _state_losses(self, stretch: LossStretch) -> None:
        """Frames that never came: one log line per stretch, and the status's values."""
        if not stretch.said:
            self.node.get_logger().warning(stretch.message(time.time_ns()))
        self._loss_values = [KeyValue(key=key, value=value) for key, value in (
            (FRAMES_LOST_KEY, str(stretch.lost)), (FRAMES_SENT_KEY, str(stretch.sent)),
            (FRAMES_LOST_SINCE_KEY, f'{stretch.since_ns * 1e-9:.6f}'),
            (FRAMES_LOST_CAUSE_KEY, stretch.cause))]
        self._say(DiagnosticStatus.OK if stretch.ended else DiagnosticStatus.WARN,
                  f'frames lost: {stretch.lost} of {stretch.sent}'
                  + (' (none since)' if stretch.ended else ''), again=True)

    def _state_ages(self) -> None:
        """How old the driver's frames come (frame_ages), in the status and, the first time,
        in the log."""
        if not self._age_values:
            self.node.get_logger().info(
                f'{self.name}: frames from {self.image_topic} arrive up to '
                f'{self.ages.frame_age_s * 1e3:.1f} ms after their stamps, at '
                f'{self.ages.frame_rate_hz:.1f} Hz; a capture in motion is up to '
                f'{self.ages.capture_age_s * 1e3:.1f} ms old when published')
        self._age_values = [KeyValue(key=key, value=value)
                            for key, value in self.ages.values(self.image_topic)]
        if self._said is not None:
            self._say(self._said_level, self._said, again=True)

    def _refuse(self, error: CameraConfigError | str) -> None:
        if not isinstance(error, str):
            self.node.get_logger().warning(f'{self.name}: frame refused: {error}')
        self._say(DiagnosticStatus.ERROR, f'frame refused: {error}')
        self.stillness.reset()
        self.tracker.reset()
        self._last_seen = None

    def _identify(self, msg: ImageLike) -> list[Sighting] | None:
        """The robots in one frame of several (None: the frame is refused, and said so)."""
        if self.info_refusal is not None:
            self._refuse(self.info_refusal)
            return None
        try:
            pixels = image_array(msg, self.camera.plane.resolution_px)
            self._full_scale = max(self._full_scale, full_scale(pixels, self.camera.bit_depth))
            sightings, reason = identify(pixels, self.camera.plane, self._full_scale)
        except CameraConfigError as error:
            self._refuse(error)
            return None
        if not sightings:
            self._say(DiagnosticStatus.WARN, reason)
        return sightings

    def say_sightings(self, sightings: list[Sighting], unnamed: list[Sighting]) -> None:
        """Who a frame showed, in the status (on each change; where each unnamed robot is, in
        its values), and each new reason a robot could not be named, in the log."""
        if not sightings:
            return
        names = sorted(robot_name(s.robot) for s in sightings
                       if s.robot is not None and s.robot in self.node.robots.values())
        message = f'seen: {", ".join(names) or "nobody named"}'
        if unnamed:
            message += f'; {len(unnamed)} not named: ' + '; '.join(
                sorted({s.reason for s in unnamed}))
            for sighting in unnamed:
                if sighting.reason not in self._unnamed_said:
                    self._unnamed_said.add(sighting.reason)
                    self.node.get_logger().warning(
                        f'{self.name}: a robot at ({sighting.pose[0] * 1e3:.3f}, '
                        f'{sighting.pose[1] * 1e3:.3f}) mm: {sighting.reason}')
        if message != self._said:
            where = [KeyValue(key='not_named_at_mm', value='; '.join(
                f'{s.pose[0] * 1e3:.3f},{s.pose[1] * 1e3:.3f}' for s in unnamed))]
            self._said = message
            self._said_level = DiagnosticStatus.WARN if unnamed else DiagnosticStatus.OK
            self.status_pub.publish(DiagnosticStatus(
                level=self._said_level, name=f'tracker {self.name}', message=message,
                values=self._values + (where if unnamed else [])))

    def _see(self, msg: ImageLike) -> tuple[bool, HeldCapture | None, HeldInMotion | None]:
        """Track one frame: whether the fiducial is in it, and the capture or the capture in
        motion it gives, if any."""
        if self.info_refusal is not None:
            # Said once in the log when the CameraInfo came; in the status with every frame.
            self._refuse(self.info_refusal)
            return False, None, None
        try:
            pixels = image_array(msg, self.camera.plane.resolution_px)
            result = self.tracker(pixels)
        except CameraConfigError as error:
            self._refuse(error)
            return False, None, None
        if result.pose is None:
            self.stillness.reset()
            self._last_seen = None
            self._say(DiagnosticStatus.WARN, result.reason)
            return False, None, None
        x, y, phi = result.pose
        last, self._last_seen = self._last_seen, (join_stamp(msg.header.stamp.sec,
                                                            msg.header.stamp.nanosec), x, y)
        if not self.stillness.still(x, y):
            self._say(DiagnosticStatus.OK, 'moving')
            moving = None
            if self.in_motion_pub is not None and last is not None:
                moving = self.in_motion(join_stamp(msg.header.stamp.sec,
                                                   msg.header.stamp.nanosec), (x, y, phi), last)
            return True, None, moving
        self._say(DiagnosticStatus.OK, 'still: capturing')
        capture = capture_pose(msg.header.stamp.sec, msg.header.stamp.nanosec,
                               self.node.frame_id, x, y, phi)
        return True, (self, with_uncertainty(capture, self.camera.uncertainty(phi)), capture), None

    def in_motion(self, stamp_s: float, pose: tuple[float, float, float],
                  last: tuple[float, float, float]) -> HeldInMotion | None:
        """The frame stamped ``stamp_s`` of the moving robot (``last``: where and when this
        camera saw it before, (stamp_s, x, y)) as a capture at its exposure's middle, its spread
        grown by the blur at the speed since the last frame; none past the speed the tracker
        follows (motion_capture.trackable)."""
        x, y, phi = pose
        elapsed = stamp_s - last[0]
        if elapsed <= 0.0:
            return None
        vx, vy = (x - last[1]) / elapsed, (y - last[2]) / elapsed
        model = self.camera.model
        if not trackable(model, math.hypot(vx, vy), self.exposure_s):
            return None
        pose = capture_pose(*split_stamp(stamp_s + self.mid_exposure_after_stamp_s),
                            self.node.frame_id, x, y, phi)
        return self, with_uncertainty(pose, uncertainty_in_motion(
            model, phi, vx, vy, self.exposure_s, still=self.camera.uncertainty(phi)))

    def publish_in_motion(self, message: PoseWithCovarianceStamped) -> bool:
        """Publish a capture in motion the arbiter let through; whether it was."""
        if self.in_motion_pub is None:
            return False
        self.in_motion_pub.publish(message)
        return True


# A capture as the tracker holds it until the arbiter lets it go: its camera, then both messages.
HeldCapture = tuple[CameraReader, PoseWithCovarianceStamped, PoseStamped]
# A capture in motion, held the same way: its camera and its message.
HeldInMotion = tuple[CameraReader, PoseWithCovarianceStamped]
