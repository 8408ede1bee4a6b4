"""What the controller node publishes, built from its decisions: the wheel trajectory of a move
or a stop, and the ``/controller/status`` of a move or a goal's end (keys: README, "Status").

Plain functions over message types (no rclpy node), so that what a status says can be read
beside the decision that made it.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from omni_micro_common.conventions import (
    BASE_FRAME,
    CAPTURE_AGE_KEY,
    IMAGE_TOPIC_KEY,
    JOINT_NAMES,
    OUTCOME_KEY,
    split_stamp,
)
from omni_micro_common.topic_names import namespaced_frame
from omni_micro_control.capture_ages import allowance_words
from omni_micro_control.feedback import Finished, Move, Outcome, VisionFeedbackController
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.model_based import ModelBasedPlanner, learnt_offsets
from omni_micro_control.servo_config import ServoCommand, ServoConfig
from omni_micro_control.servo_session import ServoSession
from omni_micro_sim.profile import WheelSpeedProfile
from omni_micro_sim.wheel_trajectory import points_from_profile

STATUS_LEVELS = {Outcome.REACHED: DiagnosticStatus.OK, Outcome.COMPLETED: DiagnosticStatus.OK,
                 Outcome.GAVE_UP: DiagnosticStatus.WARN, Outcome.CANCELLED: DiagnosticStatus.WARN,
                 Outcome.LOST: DiagnosticStatus.ERROR, Outcome.UNRESOLVED: DiagnosticStatus.WARN}


def trajectory_frame(namespace: str) -> str:
    """The frame of the commands to the robot in ``namespace``: its base (a trajectory's
    joints are the robot's own), ``robot_1/base_link`` in a fleet (REP-105 per robot)."""
    return namespaced_frame(namespace, BASE_FRAME)


def move_trajectory(move: Move | ServoCommand, profile: WheelSpeedProfile,
                    frame: str) -> JointTrajectory:
    """The move (or a servo's command) as the robot takes it: steering, then the wheels along
    ``profile``, from the move's start (its header stamp)."""
    msg = JointTrajectory()
    msg.header.stamp.sec, msg.header.stamp.nanosec = split_stamp(move.start_s)
    msg.header.frame_id = frame
    msg.joint_names = list(JOINT_NAMES)
    for point in points_from_profile(move.steering_rad, profile):
        sec, nanosec = split_stamp(point.time_from_start_s)
        msg.points.append(JointTrajectoryPoint(
            positions=list(point.positions), velocities=list(point.velocities),
            time_from_start=Duration(sec=sec, nanosec=nanosec)))
    return msg


def stop_trajectory(decided_at_ns: int, frame: str) -> JointTrajectory:
    """An empty trajectory: the dynamics (or the real robot) ramps the wheels down now.

    Stamped with the robot's time when it was decided, so that it can be told apart from the
    moves (the lockstep waits for the last command by its stamp)."""
    msg = JointTrajectory()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(decided_at_ns, 1_000_000_000)
    msg.header.frame_id = frame
    msg.joint_names = list(JOINT_NAMES)
    return msg


def ready_line(config: FeedbackConfig | ServoConfig, uncertainty_source: str) -> str:
    """The log line of a controller ready to take a goal: its mode and main settings."""
    if isinstance(config, ServoConfig):
        return (f'controller ready (servo mode): replans every {config.replan_period_s:g} s from '
                f'captures in motion at most {config.capture_age_s:g} s old, crawls the last '
                f'{config.crawl_m * 1e3:g} mm, tolerance {config.tolerance_m * 1e6:g} um, '
                f'{config.captures_per_stop} capture(s) at the stop, uncertainty from '
                f'{uncertainty_source}')
    return (f'controller ready ({config.mode} mode): timer2 {config.settle_wait_s:g} s, timer1 '
            f'{config.far_period_s:g}/{config.near_period_s:g} s beyond/within '
            f'{config.comparator_distance_m * 1e3:g} mm, '
            f'tolerance {config.tolerance_m * 1e6:g} um, {config.captures_per_stop} '
            f'capture(s) per stop, uncertainty from {uncertainty_source}')


def servo_move(session: ServoSession, command: ServoCommand) -> tuple[str, dict[str, str]]:
    """The log line and the ``moving`` status's values of a servo's move from a stop."""
    goal, estimate = session.goal_m, session.servo.filter
    assert goal is not None and estimate is not None
    remaining = math.hypot(goal[0] - estimate.mean[0], goal[1] - estimate.mean[1])
    moves = session.servo.moves
    line = (f'move {moves} (servo): {remaining * 1e3:.4f} mm to go; theta1 '
            f'{math.degrees(command.steering_rad):.3f} deg, wheels for '
            f'{command.profile.end_time_s:.4f} s, corrected while rolling')
    return line, {'periods': str(moves), 'remaining_m': repr(remaining), 'rule': 'servo'}


def move_line(move: Move, planner: object) -> str:
    """The log line of a move: what the camera saw and what the wheels are told; the model
    mode's planning time (wall clock: the log's, never a recorded status's, so that the same
    seed records the same bag)."""
    planned = (f'; planned in {planner.log.plan_wall_s[-1]:.4f} s'
               if isinstance(planner, ModelBasedPlanner) else '')
    return (f'period {move.period} ({move.rule}): {move.observation.camera} sees '
            f'({move.observation.x_m * 1e3:.4f}, {move.observation.y_m * 1e3:.4f}) mm, '
            f'{move.remaining_m * 1e3:.4f} mm to go; theta1 '
            f'{math.degrees(move.steering_rad):.3f} deg for {move.duration_s:.4f} s'
            + (f'; {move.note}' if move.note else '') + planned)


def move_values(move: Move, planner: object) -> dict[str, str]:
    """A ``moving`` status's values; the model mode adds its estimate."""
    values = {'periods': str(move.period), 'remaining_m': repr(move.remaining_m),
              'rule': move.rule}
    if isinstance(planner, ModelBasedPlanner):
        values.update({f'estimate.{name}': repr(value)
                       for name, value in planner.estimate().items()})
    return values


def servo_values(session: ServoSession) -> dict[str, str]:
    """What a servo's goal end adds: its stops, its plans made while rolling and the captures in
    motion it took in."""
    return {'stops': str(session.servo.stops), 'replans': str(session.servo.replans),
            'captures_in_motion': str(session.captures_in_motion)}


def end_values(controller: VisionFeedbackController | ServoSession) -> dict[str, str]:
    """What a goal's end adds to its outcome (:func:`outcome_values`) in the controller's mode:
    the servo's counts, and the offsets learnt (``estimate.xi2``, ``estimate.xi3``, rad)."""
    values = servo_values(controller) if isinstance(controller, ServoSession) else {}
    learnt = learnt_offsets(controller)
    if learnt is not None:
        values.update({'estimate.xi2': repr(learnt[0]), 'estimate.xi3': repr(learnt[1])})
    return values


def outcome_values(finished: Finished, robot_time_s: float,
                   goal_m: tuple[float, float] | None) -> dict[str, str]:
    """A goal's end: its outcome, periods and reason, what the decisive capture saw, the goal."""
    values = {OUTCOME_KEY: finished.outcome.value, 'periods': str(finished.periods),
              'reason': finished.reason,
              # The run's time as reported: its decisive capture, else the robot's last
              # report (the status's own time may be later: a timeout).
              'sim_time_s': repr(finished.observation.stamp_s if finished.observation
                                 else robot_time_s)}
    if finished.observation is not None:
        seen = finished.observation
        values.update(measured_x_m=repr(seen.x_m), measured_y_m=repr(seen.y_m),
                      measured_phi_rad=repr(seen.phi_rad), camera=seen.camera,
                      capture_stamp_s=repr(seen.stamp_s))
    if goal_m is not None:
        values.update(goal_x_m=repr(goal_m[0]), goal_y_m=repr(goal_m[1]))
    return values


def stated_age(camera: str, values: dict[str, str], captures: str = 'captures') -> str:
    """What a tracker's status (``values``) says of ``camera``'s captures' age, as a
    controller's line names it."""
    return (f'{camera}: frames from {values.get(IMAGE_TOPIC_KEY, "the camera driver")} give '
            f'{captures} up to {float(values[CAPTURE_AGE_KEY]) * 1e3:.1f} ms old '
            '(tracker_status)')


def capture_age_line(camera: str, values: dict[str, str], own_s: float, bound_s: float) -> str:
    """The line a servo logs when a driver's captures in motion come later than its bound
    (``values``: the tracker's status)."""
    return (f"{stated_age(camera, values, 'captures in motion')}, later than the servo's bound "
            f'of {own_s * 1e3:.1f} ms (servo.capture_age_s): it starts its corrections '
            f"{bound_s * 1e3:.1f} ms after a capture's stamp")


def take_tracker_status(controller: ServoSession | VisionFeedbackController, camera: str,
                        status: Iterable[KeyValue]) -> str | None:
    """A tracker's status (``camera``'s) taken by the controller: the line to log if the age it
    states for its captures grew the servo's bound (:func:`capture_age_line`) or the other
    modes' allowance before their capture timeouts."""
    values = {item.key: item.value for item in status}
    if isinstance(controller, ServoSession):
        own = controller.config.capture_age_s
        bound = controller.take_capture_age(camera, values.get(CAPTURE_AGE_KEY))
        return None if bound is None else capture_age_line(camera, values, own, bound)
    allowance = controller.take_capture_age(camera, values.get(CAPTURE_AGE_KEY))
    if allowance is None:
        return None
    config = controller.config
    return (f'{stated_age(camera, values)}: the capture timeouts ({config.max_capture_tries} x '
            f'{config.capture_timeout_s:g} s) count from {allowance * 1e3:.1f} ms after timer2')


def waiting_line(tries: int, config: FeedbackConfig, allowance_s: float = 0.0) -> str:
    """The line a controller logs when a capture timeout passes and it waits again
    (``allowance_s``: how late the cameras say their captures come)."""
    return (f'no capture {tries} x {config.capture_timeout_s:g} s{allowance_words(allowance_s)} '
            f'after timer2; waiting again (try {tries + 1} of {config.max_capture_tries})')
