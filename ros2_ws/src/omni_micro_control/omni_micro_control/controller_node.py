"""ROS 2 adapter of the vision-feedback controller (section 4.1).

Subscribes:
  /goal_pose           geometry_msgs/PoseStamped in the ``platform`` frame (x, y; heading unused)
  /camera/<name>/pose_with_covariance   captures with their uncertainty (the camera
                       contract, README); with capture_uncertainty: fixed, the bare
                       /camera/<name>/pose captures and the fixed_uncertainty.<name> params
  /camera/<name>/pose_in_motion   in the servo mode: captures of the moving robot
  /camera/<name>/tracker_status   how old a driver's captures come (a servo's bound on their
                       latency; the other modes' capture timeouts wait that much longer)
  /joint_states        wheel states, to know when a commanded move is over
Publishes:
  /wheel_trajectory    trajectory_msgs/JointTrajectory moves (and an empty one = stop)
  /controller/status   diagnostic_msgs/DiagnosticStatus: phase, periods and the outcome
                       (reached / gave_up / lost / completed / cancelled), latched
  /lockstep            its report after each input (omni_micro_common.lockstep)
Serves:
  ~/cancel             std_srvs/Trigger: the goal under way ends ``cancelled`` and the robot is
                       told to stop (a fleet's guard stops every robot so on the bench)
Time is the robot's, from the stamps of its wheel states (no /clock); the decisions are taken on
capture stamps, see :mod:`omni_micro_control.feedback`; a goal counts from its arrival, or from its
stamp (``goal_time: stamp``, as a fleet's coordinator hands them out). ``mode: model`` plans the
moves through the slip core and identifies the robot as it goes
(:mod:`omni_micro_control.model_based`); ``mode: servo`` keeps it rolling and corrects it from the
captures in motion (:mod:`omni_micro_control.servo_session`). On shutdown the robot is told to
stop.
"""

from __future__ import annotations

import functools
import time
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from omni_micro_common.controller_status import status_message
from omni_micro_common.conventions import (
    STATUS_TIME_KEY,
    join_stamp,
    stamp_ns,
)
from omni_micro_common.lockstep import Ack
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.publication_counts import PublicationCounter
from omni_micro_common.qos import CAPTURE_QOS, DATA_QOS, PER_TICK_SUBSCRIPTION_EVENTS, STATUS_QOS
from omni_micro_common.reader_matching import node_list_parameter, when_readers_matched
from omni_micro_common.tick_messages import read_wheel_state, robot_joint_state_template
from omni_micro_common.topic_names import (
    CAMERA_STATUS_TOPIC,
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    CONTROLLER_STATUS_TOPIC,
    GOAL_TOPIC,
    JOINT_STATES_TOPIC,
    TRACKER_STATUS_TOPICS,
    WHEEL_TRAJECTORY_TOPIC,
)
from omni_micro_control.capture_intake import CaptureIntake
from omni_micro_control.controller_messages import (
    STATUS_LEVELS,
    end_values,
    move_line,
    move_trajectory,
    move_values,
    outcome_values,
    ready_line,
    servo_move,
    stop_trajectory,
    take_tracker_status,
    trajectory_frame,
    waiting_line,
)
from omni_micro_control.controller_parameters import declare_controller_parameters, reconfigure
from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import Finished, Move, Outcome, Phase, VisionFeedbackController
from omni_micro_control.move_watcher import MoveWatcher
from omni_micro_control.platform import goal_error
from omni_micro_control.servo_config import ServoCommand
from omni_micro_control.servo_session import ServoSession
from omni_micro_sim.errors import CommandError, ParameterError
from omni_micro_sim.profile import move_profile

# How often, in the robot's time, the capture timeouts are checked.
TIMEOUT_CHECK_S = 0.05


class ControllerNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options as rclpy's Node takes them: tests build the node in-process with them.
        super().__init__('controller_node', **node_options)
        settings = declare_controller_parameters(self)
        self.limits = settings.limits
        self.frame_id = settings.frame_id
        self.platform_center, self.platform_size = settings.platform_center, settings.platform_size
        self.uncertainty_source = settings.uncertainty_source
        self.controller = settings.controller()
        self.watcher = MoveWatcher()
        self.robot_time_s = 0.0
        self._robot_time_ns = 0
        self._command_ns: int | None = None
        self._outcome_ns: int | None = None   # the last goal's end, for a coordinator
        self.goals_at_stamp = settings.goal_time == 'stamp'
        self.captures = CaptureIntake(self, self.frame_id, settings.fixed_uncertainty,
                                      servo=isinstance(self.controller, ServoSession))
        self.publication_counter = PublicationCounter()
        count = self.publication_counter.wrap
        self.trajectory_pub = count(self.create_publisher(JointTrajectory, WHEEL_TRAJECTORY_TOPIC,
                                                          DATA_QOS))
        self.status_pub = count(self.create_publisher(DiagnosticStatus, CONTROLLER_STATUS_TOPIC,
                                                      STATUS_QOS))
        self.lockstep = LockstepReporter(self)
        # Raw, read in place (tick_messages): the per-tick message without its conversion.
        self._joint_state = robot_joint_state_template(self.get_namespace().strip('/'))
        self._trajectory_frame = trajectory_frame(self.get_namespace().strip('/'))
        writers = [(self.trajectory_pub, node_list_parameter(self, 'trajectory_readers')),
                   (self.status_pub, node_list_parameter(self, 'status_readers'))]
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.create_service(Trigger, '~/cancel', self._on_cancel)
        self._timeout_checks = 0
        self._scripted_goal = settings.goal
        self.get_logger().info(ready_line(settings.servo or settings.config,
                                          self.uncertainty_source))
        # Says it is idle, and listens, once every trajectory_readers' reader of its moves and
        # every status_readers' reader of its statuses is matched: a move sent before is lost,
        # and a latched status sent before reaches a reader only as history, which Fast DDS
        # does not always deliver to a reader matched late (eProsima/Fast-DDS#3822: a fleet's
        # bag lacked one controller's 'idle').
        when_readers_matched(self, writers, self._listen)

    def _listen(self) -> None:
        self.publish_status(DiagnosticStatus.OK, 'idle', at_s=0.0)
        self.create_subscription(JointState, JOINT_STATES_TOPIC, self._on_joint_state, DATA_QOS,
                                 raw=True, event_callbacks=PER_TICK_SUBSCRIPTION_EVENTS)
        covariance = self.uncertainty_source == 'covariance'
        for name in CAPTURE_TOPICS:
            self.create_subscription(
                PoseWithCovarianceStamped if covariance else PoseStamped,
                (CAPTURE_COVARIANCE_TOPICS if covariance else CAPTURE_TOPICS)[name],
                functools.partial(self.captures.on_capture_with_covariance if covariance
                                  else self.captures.on_capture, camera=name), CAPTURE_QOS)
            if self.captures.motion_handled_ns is not None:
                self.create_subscription(
                    PoseWithCovarianceStamped, CAPTURE_IN_MOTION_TOPICS[name],
                    functools.partial(self.captures.on_capture_with_covariance, camera=name,
                                      in_motion=True), CAPTURE_QOS)
            self.create_subscription(
                DiagnosticStatus, TRACKER_STATUS_TOPICS[name],
                functools.partial(self._on_tracker_status, camera=name), STATUS_QOS)
        self.create_subscription(PoseStamped, GOAL_TOPIC, self._on_goal, 10)
        self.create_subscription(DiagnosticStatus, CAMERA_STATUS_TOPIC, self._on_camera_status,
                                 STATUS_QOS)
        if self._scripted_goal is not None:
            # A scripted goal counts from time 0: the robot has been still since the start.
            x_m, y_m = self._scripted_goal
            self._accept_goal(x_m, y_m, stopped_at_s=0.0)

    def _on_goal(self, msg: PoseStamped) -> None:
        if msg.header.frame_id not in (self.frame_id, ''):
            self._reject_goal(f'goal in frame {msg.header.frame_id!r}: expected {self.frame_id!r}')
            return
        self._accept_goal(msg.pose.position.x, msg.pose.position.y, stopped_at_s=(
            join_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec) if self.goals_at_stamp
            else self.robot_time_s))

    def _accept_goal(self, x_m: float, y_m: float, stopped_at_s: float) -> None:
        problem = goal_error(float(x_m), float(y_m), self.platform_center, self.platform_size)
        if problem:
            self._reject_goal(problem)
            return
        replaced = self.controller.set_goal((float(x_m), float(y_m)), stopped_at_s)
        self.report(replaced, at_s=stopped_at_s)
        self.get_logger().info(f'goal ({x_m * 1e3:.4f}, {y_m * 1e3:.4f}) mm, still since '
                               f'{stopped_at_s:.3f} s')
        # Acted on first: on /lockstep by 'settling'.
        held = self.captures.before_the_goal.since(stopped_at_s)
        for seen in held:
            self.act(self.controller.on_capture(seen), at_s=seen.stamp_s)
        if not held or self.controller.phase is not Phase.MOVING:   # else 'moving' said it
            self.publish_status(DiagnosticStatus.OK, 'settling', at_s=stopped_at_s)

    def _reject_goal(self, problem: str) -> None:
        """A goal refused leaves the one under way (or none) as it was."""
        self.get_logger().warning(f'rejected {problem}; staying as it was')
        self.publish_status(DiagnosticStatus.WARN, 'goal rejected', at_s=self.robot_time_s,
                             reason=problem)

    def _on_joint_state(self, data: bytes) -> None:
        wheels = read_wheel_state(self._joint_state, data)
        if wheels is None:
            return
        stamp = join_stamp(wheels.sec, wheels.nanosec)
        if self.robot_time_s == 0.0 and stamp > 0.0:
            # First word from a robot whose clock was already running (this node was started
            # late, e.g. respawned): timer2 counts from now, not from the time 0 we assumed.
            self.controller.restart_wait(stamp)
        self.robot_time_s = max(self.robot_time_s, stamp)
        self._robot_time_ns = max(self._robot_time_ns, wheels.sec * 10**9 + wheels.nanosec)
        stopped = self.watcher.on_wheel_state(wheels.rotations_rad, wheels.speeds_rad_s,
                                              wheels.steering_rate_rad_s)
        if isinstance(self.controller, ServoSession):
            self.controller.on_wheel_state(stamp, wheels.speeds_rad_s)
        elif stopped:
            self.act(self.controller.on_wheels_stopped(stamp), at_s=stamp)
        self.captures.release_held()
        # The capture timeouts on the robot's own wheel states' time (no /clock subscription).
        check = int(self.robot_time_s // TIMEOUT_CHECK_S)
        if check > self._timeout_checks:
            self._timeout_checks = check
            self._on_timer()
        self.report_lockstep()

    def report_lockstep(self) -> None:   # all received is handled, and its results published
        self.lockstep.report(Ack(
            self.get_name(), self._robot_time_ns, capture_handled_ns=self.captures.handled_ns,
            command_ns=self._command_ns,
            command_lead_ns=round(self.controller.config.command_lead_s * 1e9),
            motion_handled_ns=self.captures.motion_handled_ns, outcome_ns=self._outcome_ns))

    def act(self, decision: Move | ServoCommand | Finished | None, at_s: float) -> None:
        """``at_s``: the simulated time of its cause, which a finished goal's status carries."""
        if isinstance(decision, Move):
            self._command(decision)
        elif isinstance(decision, ServoCommand):
            self._publish_trajectory(move_trajectory(decision, decision.profile,
                                                     self._trajectory_frame))
            # A plan made again while rolling is counted at the goal's end, not said each time.
            if decision.from_rest and isinstance(self.controller, ServoSession):
                line, values = servo_move(self.controller, decision)
                self.get_logger().info(line)
                self.publish_status(DiagnosticStatus.OK, 'moving', at_s=at_s, **values)
        elif isinstance(decision, Finished):
            self.report(decision, at_s)

    def _on_camera_status(self, msg: DiagnosticStatus) -> None:
        """A camera that says it cannot see the robot ends the wait at once (one that says
        nothing is caught by the capture timeout), at the camera's time: the robot's, as far as
        this node has it, depends on which message came first."""
        if msg.level != DiagnosticStatus.OK and 'outside' in msg.message:
            said = {item.key: item.value for item in msg.values}.get(STATUS_TIME_KEY)
            at_s = float(said) if said is not None else self.robot_time_s
            self.act(self.controller.on_out_of_field(self.robot_time_s), at_s=at_s)
            self.report_lockstep()

    def _on_tracker_status(self, msg: DiagnosticStatus, camera: str) -> None:
        """How old a driver's captures come: the servo's bound, or the other modes' allowance
        before a capture timeout, grows to it."""
        line = take_tracker_status(self.controller, camera, msg.values)
        if line is not None:
            self.get_logger().warning(line)

    def _on_set_parameters(self, params: list) -> SetParametersResult:
        """Section 4.1's parameters may be tuned while the node runs, checked first."""
        return reconfigure(self.controller, {p.name: p.value for p in params})

    def _on_cancel(self, request: Trigger.Request,
                   response: Trigger.Response) -> Trigger.Response:
        response.success = True
        response.message = self.cancel_goal('cancelled on request')
        return response

    def cancel_goal(self, reason: str) -> str:
        """End the goal under way as cancelled (``reason``) and tell the robot to stop, whether
        a goal was under way or not; says which."""
        finished = self.controller.cancel(reason)
        self.report(finished, at_s=self.robot_time_s)
        self.stop_robot()
        return 'cancelled; the robot told to stop' if finished is not None else \
            'no goal under way; the robot told to stop'

    def _on_timer(self) -> None:
        """The capture timeouts (none in the servo mode: the run's timeout catches a silence)."""
        if isinstance(self.controller, ServoSession):
            return
        tries_before = self.controller.tries
        # Timeouts count the robot's own time as far as its reports have arrived, so a busy
        # machine delays them instead of firing them before the captures could arrive.
        tries, finished = self.controller.on_time(self.robot_time_s)
        if tries > tries_before and finished is None:
            self.get_logger().warning(waiting_line(tries, self.controller.config,
                                                   self.controller.capture_ages.bound_s))
        if finished is not None:
            self.report(finished, at_s=self.robot_time_s)
            self.report_lockstep()

    def _command(self, move: Move) -> None:
        assert isinstance(self.controller, VisionFeedbackController)   # it made the move
        try:
            profile = move_profile(move.duration_s, self.limits)
        except CommandError as error:
            self.get_logger().error(f'cannot build the move: {error}')
            self.report(self.controller.cancel(str(error)), at_s=move.observation.stamp_s)
            return
        self.watcher.expect(float(profile.rotation_rad()[MoveWatcher.WATCHED_WHEEL]))
        self._publish_trajectory(move_trajectory(move, profile, self._trajectory_frame))
        line = move_line(move, self.controller.planner)
        values = move_values(move, self.controller.planner)
        # A fall-back to the paper's rule in the model mode is worth a warning.
        if move.rule == 'paper' and self.controller.config.mode == 'model':
            self.get_logger().warning(line)
        else:
            self.get_logger().info(line)
        self.publish_status(DiagnosticStatus.OK, 'moving', at_s=move.observation.stamp_s,
                             **values)

    def report(self, finished: Finished | None, at_s: float) -> None:
        """Publish a goal's end; ``at_s``: the simulated time of the decision."""
        if finished is None:
            return
        if self.controller.phase is Phase.DONE:
            self.watcher.forget()   # a replaced goal keeps watching the move still running
        values = {**outcome_values(finished, self.robot_time_s, self.controller.goal_m),
                  **end_values(self.controller)}
        # Lost: never move blind. A goal replaced mid-move lets the move finish (its end is
        # what starts timer2 for the new goal); a shutdown stops the robot in main().
        if finished.outcome is Outcome.LOST:
            self.stop_robot()
        line = f'{finished.outcome.value}: {finished.reason} ({finished.periods} periods)'
        # rclpy fixes a logging call site's severity on first use: one site per severity.
        if STATUS_LEVELS[finished.outcome] == DiagnosticStatus.OK:
            self.get_logger().info(line)
        else:
            self.get_logger().warning(line)
        self.publish_status(STATUS_LEVELS[finished.outcome], finished.outcome.value, at_s=at_s,
                             **values)
        self._outcome_ns = round(at_s * 1e9)

    def publish_status(self, level: int, message: str, at_s: float, **values: str) -> None:
        self.status_pub.publish(status_message(level, message, at_s, values))

    def stop_robot(self) -> None:
        """Tell the robot to ramp its wheels down now (controller_messages.stop_trajectory)."""
        self._publish_trajectory(stop_trajectory(self._robot_time_ns, self._trajectory_frame))

    def _publish_trajectory(self, msg: JointTrajectory) -> None:
        self.trajectory_pub.publish(msg)
        self._command_ns = stamp_ns(msg.header.stamp)
        self.report_lockstep()   # at once, before any status of it


# The longest a stopping controller waits for its stop and its last status to be acknowledged:
# a reader whose process died never acknowledges, and the graph's stop must not wait on it.
STOP_HANDOVER_S = 0.2


def _stop_on_shutdown(node: ControllerNode) -> None:
    if not rclpy.ok():
        return   # the context is gone: nothing can be sent any more
    node.cancel_goal('shutdown')
    # The node goes once every reader (the robot, the recorder, the orchestration) has the stop
    # and the status: reliable writers, so acknowledged is received. Within milliseconds in a
    # graph, where a fixed wait of STOP_HANDOVER_S held every graph's stop that long.
    deadline = time.monotonic() + STOP_HANDOVER_S
    for publisher in (node.trajectory_pub, node.status_pub):
        left_s = max(0.0, deadline - time.monotonic())
        publisher.wait_for_all_acked(Duration(nanoseconds=round(left_s * 1e9)))


COMPONENT = NodeComponent(ControllerNode,
                          config_errors=(ControllerConfigError, ParameterError, CommandError),
                          on_shutdown=_stop_on_shutdown)


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
