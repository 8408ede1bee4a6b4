"""What controller_node does with a capture: held until the robot's first wheel state, read
against its frame and the robot's clock, held for a goal stamped before it that has not arrived
yet (a fleet's coordinator hands goals out so), or handed to the controller; and how far the
captures handled go, for /lockstep."""

from __future__ import annotations

from collections import deque
from typing import Any, Protocol

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import Pose, PoseStamped, PoseWithCovarianceStamped
from std_msgs.msg import Header

from omni_micro_common.conventions import (
    CaptureUncertainty,
    join_stamp,
    quaternion_to_yaw,
    stamp_ns,
)
from omni_micro_control.feedback import Finished, Move, Phase, VisionFeedbackController
from omni_micro_control.move_watcher import MoveWatcher
from omni_micro_control.observations import CapturesBeforeTheGoal, Observation, read_capture
from omni_micro_control.servo_config import ServoCommand
from omni_micro_control.servo_session import ServoSession


class ServedNode(Protocol):
    """What the intake needs of the node it serves (controller_node)."""

    controller: VisionFeedbackController | ServoSession
    watcher: MoveWatcher
    robot_time_s: float

    def get_logger(self) -> Any: ...

    def act(self, decision: Move | ServoCommand | Finished | None, at_s: float) -> None: ...

    def publish_status(self, level: int, message: str, at_s: float, **values: str) -> None: ...

    def report_lockstep(self) -> None: ...


# The most captures held for the robot's first wheel state: more than the two cameras give in a
# lockstep's lead, and a respawned controller's first moments, at their fastest.
HELD_BEFORE_THE_WHEELS = 20


class CaptureIntake:
    """controller_node's captures, still (``on_capture``, ``on_capture_with_covariance``) and in
    motion (the servo's), each handled and said so on /lockstep.

    A capture and the wheel states travel on different topics, so a capture may come before the
    robot's first wheel state (with images, the tracker's first capture in motion came so once
    in a dozen runs beside busy processes). Until that state the robot's time, and whether it
    moves, are unknown: the capture is held, and handed over once it comes (``release_held``),
    so that what the controller does with it never depends on which came first."""

    def __init__(self, node: ServedNode, frame_id: str,
                 fixed_uncertainty: dict[str, CaptureUncertainty], servo: bool) -> None:
        self.node = node
        self.frame_id = frame_id
        self.fixed_uncertainty = fixed_uncertainty
        self.before_the_goal = CapturesBeforeTheGoal()
        self.handled_ns = -1
        # A servo reports the captures in motion it has handled; the others read none.
        self.motion_handled_ns: int | None = -1 if servo else None
        self._said_mismatch: str | None = None   # the last clock mismatch logged
        self._before_the_wheels: deque[tuple[Header, Pose, CaptureUncertainty | None, str,
                                             bool]] = deque(maxlen=HELD_BEFORE_THE_WHEELS)

    def on_capture(self, msg: PoseStamped, camera: str) -> None:
        self.take(msg.header, msg.pose, self.fixed_uncertainty[camera], camera)

    def on_capture_with_covariance(self, msg: PoseWithCovarianceStamped, camera: str,
                                   in_motion: bool = False) -> None:
        try:
            uncertainty = CaptureUncertainty.from_covariance(msg.pose.covariance)
        except ValueError as error:
            self.node.get_logger().warning(f'ignored {camera} capture: {error}',
                                           throttle_duration_sec=5.0)
            uncertainty = None
        self.take(msg.header, msg.pose.pose, uncertainty, camera, in_motion)

    def take(self, header: Header, pose: Pose, uncertainty: CaptureUncertainty | None,
             camera: str, in_motion: bool = False) -> None:
        """A capture (``in_motion``: of the rolling robot) handled, said so on /lockstep; held,
        before the robot's first wheel state."""
        if self.node.watcher.latest_rotations is None:
            self._before_the_wheels.append((header, pose, uncertainty, camera, in_motion))
            return
        seen = None if uncertainty is None else self.observation(header, pose, uncertainty,
                                                                 camera)
        controller = self.node.controller
        if seen is not None and in_motion and isinstance(controller, ServoSession):
            self.node.act(controller.on_capture_in_motion(seen), at_s=seen.stamp_s)
        elif seen is not None and controller.phase in (Phase.IDLE, Phase.DONE):
            self.before_the_goal.keep(seen)
        elif seen is not None:
            self.node.act(controller.on_capture(seen), at_s=seen.stamp_s)
        if in_motion and self.motion_handled_ns is not None:
            self.motion_handled_ns = max(self.motion_handled_ns, stamp_ns(header.stamp))
        else:
            self.handled_ns = max(self.handled_ns, stamp_ns(header.stamp))
        self.node.report_lockstep()

    def release_held(self) -> None:
        """The robot's first wheel state has come: the captures that came before, handled in
        the order they came."""
        while self._before_the_wheels:
            self.take(*self._before_the_wheels.popleft())

    def observation(self, header: Header, pose: Pose, uncertainty: CaptureUncertainty,
                    camera: str) -> Observation | None:
        """The capture as the controller reads it; None (said why) if it cannot be used."""
        seen = read_capture(camera, header.frame_id, self.frame_id,
                            join_stamp(header.stamp.sec, header.stamp.nanosec),
                            (pose.position.x, pose.position.y,
                             quaternion_to_yaw(pose.orientation.z, pose.orientation.w)),
                            uncertainty, self.node.robot_time_s)
        if isinstance(seen, Observation):
            return seen
        if not seen.foreign_clock:
            self.node.get_logger().warning(seen.line, throttle_duration_sec=5.0)
        else:
            if seen.line != self._said_mismatch:
                self._said_mismatch = seen.line
                self.node.get_logger().error(seen.line)
                self.node.publish_status(DiagnosticStatus.ERROR, 'clock mismatch',
                                         at_s=self.node.robot_time_s, reason=seen.line)
            self.node.act(self.node.controller.on_foreign_capture(seen.line),
                          at_s=self.node.robot_time_s)
        return None
