"""What the controller node publishes, built from its decisions: the wheel trajectory of a move
or a stop, and the ``/controller/status`` of a move or a goal's end (keys: README, "Status").

Plain functions over message types (no rclpy node), so that what a status says can be read
beside the decision that made it.
"""

from __future__ import annotations

import math

from builtin_interfaces.msg import Duration
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from omni_micro_common.conventions import JOINT_NAMES, OUTCOME_KEY, STATUS_TIME_KEY, split_stamp
from omni_micro_control.feedback import Finished, Move, Outcome
from omni_micro_control.model_based import ModelBasedPlanner
from omni_micro_sim.profile import WheelSpeedProfile
from omni_micro_sim.wheel_trajectory import points_from_profile

STATUS_LEVELS = {Outcome.REACHED: DiagnosticStatus.OK, Outcome.COMPLETED: DiagnosticStatus.OK,
                 Outcome.GAVE_UP: DiagnosticStatus.WARN, Outcome.CANCELLED: DiagnosticStatus.WARN,
                 Outcome.LOST: DiagnosticStatus.ERROR, Outcome.UNRESOLVED: DiagnosticStatus.WARN}
# The robot's frame: a trajectory's joints are the robot's own.
TRAJECTORY_FRAME = 'base_link'


def move_trajectory(move: Move, profile: WheelSpeedProfile) -> JointTrajectory:
    """The move as the robot takes it: steering, then the wheels along ``profile``, from the
    move's start (its header stamp)."""
    msg = JointTrajectory()
    msg.header.stamp.sec, msg.header.stamp.nanosec = split_stamp(move.start_s)
    msg.header.frame_id = TRAJECTORY_FRAME
    msg.joint_names = list(JOINT_NAMES)
    for point in points_from_profile(move.steering_rad, profile):
        sec, nanosec = split_stamp(point.time_from_start_s)
        msg.points.append(JointTrajectoryPoint(
            positions=list(point.positions), velocities=list(point.velocities),
            time_from_start=Duration(sec=sec, nanosec=nanosec)))
    return msg


def stop_trajectory(decided_at_ns: int) -> JointTrajectory:
    """An empty trajectory: the dynamics (or the real robot) ramps the wheels down now.

    Stamped with the robot's time when it was decided, so that it can be told apart from the
    moves (the lockstep waits for the last command by its stamp)."""
    msg = JointTrajectory()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(decided_at_ns, 1_000_000_000)
    msg.header.frame_id = TRAJECTORY_FRAME
    msg.joint_names = list(JOINT_NAMES)
    return msg


def move_line(move: Move) -> str:
    """The log line of a move: what the camera saw and what the wheels are told."""
    return (f'period {move.period} ({move.rule}): {move.observation.camera} sees '
            f'({move.observation.x_m * 1e3:.4f}, {move.observation.y_m * 1e3:.4f}) mm, '
            f'{move.remaining_m * 1e3:.4f} mm to go; theta1 '
            f'{math.degrees(move.steering_rad):.3f} deg for {move.duration_s:.4f} s'
            + (f'; {move.note}' if move.note else ''))


def move_values(move: Move, planner: object) -> dict[str, str]:
    """A ``moving`` status's values; the model mode adds its planning time and estimate."""
    values = {'periods': str(move.period), 'remaining_m': repr(move.remaining_m),
              'rule': move.rule}
    if isinstance(planner, ModelBasedPlanner):
        values['plan_wall_s'] = f'{planner.log.plan_wall_s[-1]:.4f}'
        values.update({f'estimate.{name}': repr(value)
                       for name, value in planner.estimate().items()})
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


def status_message(level: int, message: str, at_s: float, values: dict[str, str]
                   ) -> DiagnosticStatus:
    """``at_s``: the simulated time of what the status says (a decision's capture, a goal's
    arrival), not of its publication: a bag records it at that time (STATUS_TIME_KEY), so
    that the same run records the same statuses in the same place."""
    status = DiagnosticStatus(level=level, name='omni_micro_controller', message=message,
                              hardware_id='omni_micro')
    values = {STATUS_TIME_KEY: repr(float(at_s)), **values}
    status.values = [KeyValue(key=key, value=value) for key, value in values.items()]
    return status
