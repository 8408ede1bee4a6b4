"""Several real robots on one bench (``run --robots FILE --camera external --robot external``):
what it is refused, what its drivers must publish, and how the orchestration keeps the robots
apart.

No dynamics_node and no camera_node: each robot's driver publishes ``/robot_k/joint_states`` and
reads ``/robot_k/wheel_trajectory`` on the wall clock, and a camera driver shows every robot
with the code printed on it. The graph, built by :mod:`~omni_micro_bringup.composition` as any
other, has one tracker_node that names each robot in the driver's frames (its captures in
motion on for every robot: the guard follows them moving), each robot's controller_node under
``/robot_k``, and the recorder on the wall clock, keeping the guard's stops. Nothing runs in
lockstep.

The orchestration (:mod:`omni_micro_bringup.fleet_dispatch`) hands out the planner's legs as in
simulation, each goal stamped with the wall-clock time of the end it follows (the single robot's
bench timing, per robot), once every robot's first state and a frame naming every robot have
come. No dynamics_node can see two real robots touch: :class:`BenchGuard` follows every robot's
captures and stops them all (an empty trajectory to each: ramp the wheels down now) when the
plain :class:`~omni_micro_control.fleet_guard.FleetGuard` says so, and says why on /fleet_guard.
It also reads each robot's ``/robot_k/joint_states``: a robot standing still while the camera is
slow to name it is no danger (the guard counts only the time its wheels turn unnamed).
"""

from __future__ import annotations

import functools
import time
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.duration import Duration
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.graph_result import RobotLog
from omni_micro_common.conventions import join_stamp, quaternion_to_yaw
from omni_micro_common.qos import CAPTURE_QOS, latched, profile
from omni_micro_common.tick_messages import read_wheel_state, robot_joint_state_template
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    FLEET_GUARD_TOPIC,
    JOINT_STATES_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
    robot_name,
    robot_topic,
)
from omni_micro_control.controller_messages import stop_trajectory, trajectory_frame
from omni_micro_control.fleet_guard import FleetGuard, GuardStop

# How often the guard looks (a 15 Hz camera's frames come every 67 ms).
GUARD_PERIOD_S = 0.02
# After the guard's stop: the stops go on this long after every controller has cancelled its goal.
HOLD_AFTER_STOP_S = 0.5
# The robots' joint states, read best effort: that matches a driver's reliable writer
# (ros2_control's joint_state_broadcaster) and a best-effort one alike.
WHEELS_QOS = profile(10, best_effort=True)


def check_bench(options: GraphOptions) -> None:
    """Raises UsageError for a fleet's bench that cannot be: only one of the camera and the
    robots real, or what needs a simulated robot (--composed, --respawn, markers, the view,
    camera faults)."""
    if options.camera != options.robot:
        raise UsageError('several robots on the bench take both --camera external and --robot '
                         f'external (got --camera {options.camera} --robot {options.robot}): a '
                         'real camera cannot see simulated robots, nor a simulated one real ones')
    refused = [name for name, given in (
        ('--composed', options.composed), ('--respawn', options.respawn),
        ('--markers', options.markers), ('--view', options.view is not None),
        ('camera faults', bool(options.vision_overrides))) if given]
    if refused:
        raise UsageError(f'{", ".join(refused)}: not with real robots (no simulated robot to '
                         'hold, draw or fault); leave them out')


class BenchGuard:
    """Every robot's captures (still and in motion) on the orchestration's node: into its
    route (seconds after ``origin_s``) and the guard, which a timer of that node asks every
    GUARD_PERIOD_S whatever the orchestration is waiting for (a goal being taken, a service);
    once it says stop, every robot is held stopped until the graph is down."""

    def __init__(self, node: Any, logs: list[RobotLog], cameras: list[str],
                 stop_gap_m: float, unnamed_s: float) -> None:
        self.node = node
        self.logs = logs
        self.guard = FleetGuard(len(logs), stop_gap_m=stop_gap_m, unnamed_s=unnamed_s)
        self.origin_s = 0.0
        self.stopped: GuardStop | None = None
        self.stops = [node.create_publisher(JointTrajectory,
                                            robot_topic(k, WHEEL_TRAJECTORY_TOPIC), 10)
                      for k in range(len(logs))]
        self.status = node.create_publisher(DiagnosticStatus, FLEET_GUARD_TOPIC, latched(10))
        self.cancels = [node.create_client(Trigger, f'/{robot_name(k)}/controller_node/cancel')
                        for k in range(len(logs))]
        self.timer = node.create_timer(GUARD_PERIOD_S, self._on_tick)
        self.joint_states = [robot_joint_state_template(robot_name(k))
                             for k in range(len(logs))]
        for k in range(len(logs)):
            node.create_subscription(JointState, robot_topic(k, JOINT_STATES_TOPIC),
                                     functools.partial(self._on_wheels, k), WHEELS_QOS,
                                     raw=True)
            for camera in cameras:
                for topic in (CAPTURE_COVARIANCE_TOPICS[camera],
                              CAPTURE_IN_MOTION_TOPICS[camera]):
                    node.create_subscription(PoseWithCovarianceStamped, robot_topic(k, topic),
                                             functools.partial(self._on_capture, k),
                                             CAPTURE_QOS)

    def _on_capture(self, robot: int, msg: PoseWithCovarianceStamped) -> None:
        stamp_s = join_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)
        pose = msg.pose.pose
        self.guard.saw(robot, stamp_s, pose.position.x, pose.position.y, time.monotonic())
        if self.origin_s:   # the run's route, from its start
            self.logs[robot].route.append((
                stamp_s - self.origin_s, pose.position.x, pose.position.y,
                quaternion_to_yaw(pose.orientation.z, pose.orientation.w)))

    def _on_wheels(self, robot: int, data: bytes) -> None:
        wheels = read_wheel_state(self.joint_states[robot], data)
        if wheels is not None:
            self.guard.wheels(robot, wheels.turning, time.monotonic())

    def _on_tick(self) -> None:
        if self.stopped is not None:
            # Held: a goal handed out as the stop came would start a move.
            self.stop_every_robot()
            return
        stop = self.guard.check(time.monotonic(), stamps_now_s=time.time())
        if stop is not None:
            self.halt(stop)

    def stop_every_robot(self) -> None:
        """An empty trajectory to every robot: its wheels ramp down now."""
        now_ns = time.time_ns()
        for robot, publisher in enumerate(self.stops):
            publisher.publish(stop_trajectory(now_ns, trajectory_frame(robot_name(robot))))

    def hand_over(self, timeout_s: float = 2.0) -> None:
        """Until every reader (the drivers, the recorder) has acknowledged the stops and why:
        a writer gone before then takes what it had not delivered with it."""
        deadline = time.monotonic() + timeout_s
        for publisher in (*self.stops, self.status):
            publisher.wait_for_all_acked(Duration(
                nanoseconds=max(round((deadline - time.monotonic()) * 1e9), 0)))

    def halt(self, stop: GuardStop) -> None:
        """Every robot stopped, then why, named."""
        self.stop_every_robot()
        self.stopped = stop
        self.status.publish(DiagnosticStatus(
            level=DiagnosticStatus.ERROR, name='fleet guard', message=stop.reason,
            values=[KeyValue(key='kind', value=stop.kind),
                    KeyValue(key='robots', value=','.join(robot_name(k) for k in stop.robots)),
                    KeyValue(key='stopped', value=','.join(robot_name(k)
                                                           for k in range(len(self.logs))))]))
