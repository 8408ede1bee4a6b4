"""Several real robots on one bench (``run --robots FILE --camera external --robot external``):
what the graph starts, and how the orchestration keeps the robots apart.

No dynamics_node and no camera_node: each robot's driver publishes ``/robot_k/joint_states`` and
reads ``/robot_k/wheel_trajectory`` on the wall clock, and a camera driver shows every robot
with the code printed on it. The graph starts one tracker_node that names each robot in the
driver's frames (its captures in motion on for every robot: the guard follows them moving),
each robot's controller_node under ``/robot_k``, and the recorder on the wall clock. Nothing
runs in lockstep.

The orchestration (:mod:`omni_micro_bringup.fleet_graph`) hands out the planner's legs as in
simulation, each goal stamped with the wall-clock time of the end it follows (the single robot's
bench timing, per robot), once every robot's first state and a frame naming every robot have
come. No dynamics_node can see two real robots touch: :class:`BenchGuard` follows every robot's
captures and stops them all (an empty trajectory to each: ramp the wheels down now) when the
plain :class:`~omni_micro_control.fleet_guard.FleetGuard` says so, and says why on /fleet_guard.
"""

from __future__ import annotations

import functools
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.duration import Duration
from std_srvs.srv import Trigger
from trajectory_msgs.msg import JointTrajectory

from omni_micro_bringup.composition import (
    RECORDER_NODE,
    bench_cameras,
    recorded_topics,
    recorder_spec,
)
from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.graph_result import RobotLog
from omni_micro_bringup.node_overrides import capture_uncertainty_of, captures_read_by
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_bringup.params_files import graph_params_file
from omni_micro_bringup.robot_namespaces import in_namespace, namespaced_params
from omni_micro_common.conventions import join_stamp, quaternion_to_yaw
from omni_micro_common.qos import CAPTURE_QOS, latched
from omni_micro_common.topic_names import (
    CAMERA_STATUS_TOPIC,
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    CLOCK_TOPIC,
    FLEET_GUARD_TOPIC,
    JOINT_STATES_TOPIC,
    ODOM_TOPIC,
    TRACKER_STATUS_TOPICS,
    WHEEL_SLIP_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
    camera_info_beside,
    robot_name,
    robot_topic,
)
from omni_micro_control.controller_messages import stop_trajectory
from omni_micro_control.fleet_files import controller_settings
from omni_micro_control.fleet_guard import FleetGuard, GuardStop

# How often the guard looks (a 15 Hz camera's frames come every 67 ms).
GUARD_PERIOD_S = 0.02
# After the guard's stop: the stops go on this long after every controller has cancelled its goal.
HOLD_AFTER_STOP_S = 0.5


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


def bench_specs(options: GraphOptions, count: int, modes: list[str],
                folder: Path) -> list[NodeSpec]:
    """The processes of a fleet's bench: the tracker naming every robot in the drivers'
    frames, each robot's controller_node under its namespace (reading the shared tracker's
    statuses: how old the driver's frames come), and with ``options.record`` the recorder on
    the wall clock."""
    shipped = (graph_params_file(), *options.params_files)
    names = [robot_name(k) for k in range(count)]
    cameras = bench_cameras(options)
    tracker = {'robots': names, 'captures_in_motion': True,
               **captures_read_by([f'{robot}/controller_node' for robot in names], recorded=False,
                                  capture_uncertainty=capture_uncertainty_of(
                                      options.params_files, {})),
               'cameras': sorted(cameras),
               **{key: value for camera, topic in cameras.items()
                  for key, value in ((f'{camera}.image_topic', topic),
                                     (f'{camera}.info_topic', camera_info_beside(topic)))}}
    recorder = None
    if options.record is not None:
        # What a real robot's bench publishes: no clock, odometry, slip or markers; captures of
        # the tracked cameras only, every robot's in motion (the guard's) and the guard's stops.
        untracked = tuple(topic for name in CAPTURE_TOPICS if name not in cameras
                          for topic in (CAPTURE_TOPICS[name], CAPTURE_COVARIANCE_TOPICS[name]))
        topics = recorded_topics(names, markers=False, without=(
            CLOCK_TOPIC, ODOM_TOPIC, WHEEL_SLIP_TOPIC, CAMERA_STATUS_TOPIC, *untracked),
            in_motion=names, cameras=sorted(cameras))
        # Whole: the log keeps what came after the last goal's end too (a guard's stop, the
        # robots coming to rest).
        spec = recorder_spec(options.record, options.storage, [*topics, FLEET_GUARD_TOPIC],
                             whole=True)
        recorder = replace(spec, params=shipped, overrides={
            **spec.overrides, 'lockstep_ticks': False, 'log_clock': 'wall',
            **({'driver_images': sorted(cameras.values())} if options.record_images else {})})
    specs = [NodeSpec('omni_micro_vision', 'tracker_node', params=shipped, overrides=tracker)]
    for k in range(count):
        specs.append(in_namespace(NodeSpec('omni_micro_control', 'controller_node', {
            'goal_time': 'stamp', **controller_settings(modes[k]),
            # The drivers' readers are not the graph's to name: only the recorder's.
            'trajectory_readers': [RECORDER_NODE] if recorder else []},
            params=tuple(namespaced_params(list(shipped), names[k], folder))),
            names[k], shared=tuple(TRACKER_STATUS_TOPICS.values())))
    return [*specs, *((recorder,) if recorder else ())]


def bench_publications(count: int, image_topics: list[str]) -> dict[str, str]:
    """What the drivers must publish, each with whose it is."""
    return {**{robot_topic(k, JOINT_STATES_TOPIC): f"{robot_name(k)}'s driver"
               for k in range(count)},
            **{topic: 'the camera driver' for topic in image_topics}}


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
        for k in range(len(logs)):
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
        for publisher in self.stops:
            publisher.publish(stop_trajectory(now_ns))

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
