"""A fleet run as a rosbag2 bag: each robot's odometry, goals and goals reached under its
namespace.

Per robot k, ``/robot_k/odom`` (nav_msgs/Odometry, REP-105 frames ``robot_k/odom`` ->
``robot_k/base_link``, twist in the robot's frame) at ``ODOM_RATE_HZ``, ``/robot_k/goal_pose``
(each goal its controller was handed, in the ``platform`` frame: every point of its legs, the
last of a leg its task's goal, as the graph's coordinator sends them, each stamped with the end
it follows) and ``/robot_k/controller/status`` (each of those goals ended, as the robot's
controller node says it: ``reached``, or ``completed`` by an open-loop move, at the time of what
decided it, with the goal); ``/clock``, the simulated time, at the same rate. Every message
is logged at its simulated time. ``omni-micro replay --robot k`` publishes one robot's topics
under the single robot's names (``/odom``, ``/goal_pose``, ``/controller/status``).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from omni_micro_common.controller_status import status_message
from omni_micro_common.conventions import (
    BASE_FRAME,
    ODOM_FRAME,
    PLATFORM_FRAME,
    yaw_to_quaternion,
)
from omni_micro_common.topic_names import (
    CLOCK_TOPIC,
    CONTROLLER_STATUS_TOPIC,
    GOAL_TOPIC,
    ODOM_TOPIC,
    namespaced_frame,
    robot_name,
    robot_topic,
)

# One odometry sample in this many simulated seconds (the viewer's and analyze's rate, not the
# dynamics' 50 Hz: a fleet run of 8 robots lasts minutes).
ODOM_RATE_HZ = 10.0


def write_fleet_bag(path: Path, result: Any, period_s: float) -> int:
    """Write the bag of ``result`` (a fleet twin run) into ``path``; return how many messages it
    holds. ``path`` must not exist."""
    from builtin_interfaces.msg import Time
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message
    from rosgraph_msgs.msg import Clock

    from omni_micro_tools.bags import open_writer
    from omni_micro_tools.topics import RECORDABLE_TOPICS

    every = max(1, round(1.0 / (ODOM_RATE_HZ * period_s)))
    topics = {CLOCK_TOPIC: RECORDABLE_TOPICS[CLOCK_TOPIC]}
    for robot in range(len(result.robots)):
        topics[robot_topic(robot, ODOM_TOPIC)] = RECORDABLE_TOPICS[ODOM_TOPIC]
        topics[robot_topic(robot, GOAL_TOPIC)] = RECORDABLE_TOPICS[GOAL_TOPIC]
        topics[robot_topic(robot, CONTROLLER_STATUS_TOPIC)] = \
            RECORDABLE_TOPICS[CONTROLLER_STATUS_TOPIC]
    events: list[tuple[int, str, bytes]] = []

    def stamp(time_s: float) -> Time:
        nanoseconds = round(time_s * 1e9)
        return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)

    clock_route = result.robots[0].route_m if result.robots else []
    for index in range(0, len(clock_route), every):
        time_s = float(clock_route[index][0])
        events.append((round(time_s * 1e9), CLOCK_TOPIC,
                       serialize_message(Clock(clock=stamp(time_s)))))
    for robot, run in enumerate(result.robots):
        odom_topic = robot_topic(robot, ODOM_TOPIC)
        route = run.route_m
        for index in range(0, len(route), every):
            row = route[index]
            time_s, x, y, phi = float(row[0]), float(row[1]), float(row[2]), float(row[3])
            before = route[max(0, index - 1)]
            dt = time_s - float(before[0])
            vx = (x - float(before[1])) / dt if dt > 0 else 0.0
            vy = (y - float(before[2])) / dt if dt > 0 else 0.0
            omega = (phi - float(before[3])) / dt if dt > 0 else 0.0
            message = Odometry()
            message.header.stamp = stamp(time_s)
            message.header.frame_id = namespaced_frame(robot_name(robot), ODOM_FRAME)
            message.child_frame_id = namespaced_frame(robot_name(robot), BASE_FRAME)
            message.pose.pose.position.x, message.pose.pose.position.y = x, y
            orientation = message.pose.pose.orientation
            orientation.z, orientation.w = yaw_to_quaternion(phi)
            # REP-105: the twist in the child frame.
            message.twist.twist.linear.x = math.cos(phi) * vx + math.sin(phi) * vy
            message.twist.twist.linear.y = -math.sin(phi) * vx + math.cos(phi) * vy
            message.twist.twist.angular.z = omega
            events.append((round(time_s * 1e9), odom_topic, serialize_message(message)))
        for stamp_s, x_m, y_m in run.goal_poses:
            message = PoseStamped()
            message.header.stamp = stamp(stamp_s)
            message.header.frame_id = PLATFORM_FRAME
            message.pose.position.x, message.pose.position.y = x_m, y_m
            message.pose.orientation.w = 1.0
            events.append((round(stamp_s * 1e9), robot_topic(robot, GOAL_TOPIC),
                           serialize_message(message)))
        # The last goal of a robot lost, or of a run out of time, has no end.
        for (ended_s, outcome), (_, x_m, y_m) in zip(run.goal_pose_ends, run.goal_poses,
                                                     strict=False):
            status = status_message(DiagnosticStatus.OK, outcome, ended_s,
                                    {'goal_x_m': repr(float(x_m)), 'goal_y_m': repr(float(y_m))})
            events.append((round(ended_s * 1e9), robot_topic(robot, CONTROLLER_STATUS_TOPIC),
                           serialize_message(status)))
    writer, connections = open_writer(path, 'mcap', topics)
    try:
        for time_ns, topic, data in sorted(events, key=lambda event: event[:2]):
            writer.write(connections[topic], time_ns, data)
    finally:
        writer.close()
    return len(events)
