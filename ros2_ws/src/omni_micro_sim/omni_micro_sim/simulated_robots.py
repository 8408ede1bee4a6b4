"""The robots a dynamics node simulates on its one clock: each its grid, its topics and frames.

One robot (the default) publishes under the graph's names (``/odom``, frames ``odom`` ->
``base_link``); robot ``robot_k`` of a fleet under its namespace (``/robot_k/odom``,
frames ``robot_k/odom`` -> ``robot_k/base_link``, REP-105 with a prefix per robot, as
multi-robot TF trees do) and takes its commands on ``/robot_k/wheel_trajectory``.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from omni_micro_common.conventions import body_twist, yaw_to_quaternion
from omni_micro_common.qos import DATA_QOS
from omni_micro_common.tick_messages import tick_templates
from omni_micro_common.topic_names import (
    JOINT_STATES_THROTTLE_TOPIC,
    JOINT_STATES_TOPIC,
    ODOM_THROTTLE_TOPIC,
    ODOM_TOPIC,
    WHEEL_SLIP_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
    is_plain_name,
    namespaced_frame,
    namespaced_topic,
)
from omni_micro_sim.errors import ParameterError
from omni_micro_sim.stepper import GridSimulator, Sample


def check_namespaces(robots: list[str]) -> None:
    """Raises ParameterError for a namespace that is not one plain ROS name, or twice."""
    for name in robots:
        if not is_plain_name(name):
            raise ParameterError(f'robots: each must be a plain name (letters, digits, _; '
                                 f'a letter first), got {name!r}')
    twice = sorted({name for name in robots if robots.count(name) > 1})
    if twice:
        raise ParameterError(f'robots: {twice} named more than once')


def touching(robots: list[SimulatedRobot], samples: list[Sample]
             ) -> list[tuple[SimulatedRobot, SimulatedRobot, float]]:
    """Every two robots whose chassis discs overlap in ``samples``, with their centres'
    distance (contact forces are not simulated: the slip model has no force between robots)."""
    found = []
    for a, b in itertools.combinations(range(len(robots)), 2):
        gap = math.hypot(samples[a].state.x_m - samples[b].state.x_m,
                         samples[a].state.y_m - samples[b].state.y_m)
        reach = (robots[a].grid.simulator.params.chassis_radius_m
                 + robots[b].grid.simulator.params.chassis_radius_m)
        if gap < reach:
            found.append((robots[a], robots[b], gap))
    return found


class SimulatedRobot:
    """One robot of the dynamics node: its grid, what it publishes each tick, its commands."""

    def __init__(self, node: Node, namespace: str, grid: GridSimulator, odom_frame: str,
                 base_frame: str, per_tick: Callable[[type, str], Any],
                 on_trajectory: Callable[[SimulatedRobot, JointTrajectory], None]) -> None:
        self.namespace = namespace
        self.grid = grid
        self.templates = tick_templates(namespaced_frame(namespace, odom_frame),
                                        namespaced_frame(namespace, base_frame))
        self.odom_pub = per_tick(Odometry, namespaced_topic(namespace, ODOM_TOPIC))
        self.joint_pub = per_tick(JointState, namespaced_topic(namespace, JOINT_STATES_TOPIC))
        self.slip_pub = per_tick(JointState, namespaced_topic(namespace, WHEEL_SLIP_TOPIC))
        self.odom_throttle_pub = per_tick(Odometry,
                                          namespaced_topic(namespace, ODOM_THROTTLE_TOPIC))
        self.joint_throttle_pub = per_tick(
            JointState, namespaced_topic(namespace, JOINT_STATES_THROTTLE_TOPIC))
        self.publishers = (self.odom_pub, self.joint_pub, self.slip_pub, self.odom_throttle_pub,
                           self.joint_throttle_pub)
        node.create_subscription(JointTrajectory,
                                 namespaced_topic(namespace, WHEEL_TRAJECTORY_TOPIC),
                                 lambda msg: on_trajectory(self, msg), DATA_QOS)

    @property
    def label(self) -> str:
        return self.namespace or 'the robot'

    def publish(self, sample: Sample, sec: int, nanosec: int, throttle: bool,
                slip: bool) -> None:
        templates = self.templates
        state = sample.state
        odometry = templates.odometry.encode((
            sec, nanosec, state.x_m, state.y_m, *yaw_to_quaternion(state.phi_rad),
            *body_twist(state.phi_rad, state.vx_m_s, state.vy_m_s), state.omega_rad_s))
        self.odom_pub.publish(odometry)
        joint_state = templates.joint_state.encode((
            sec, nanosec, sample.steering_rad, *map(float, sample.wheel_rotations_rad),
            sample.steering_rate_rad_s, *map(float, sample.wheel_speeds_rad_s)))
        self.joint_pub.publish(joint_state)
        if throttle:
            self.odom_throttle_pub.publish(odometry)
            self.joint_throttle_pub.publish(joint_state)
        if not slip:
            return
        self.slip_pub.publish(templates.slip.encode((
            sec, nanosec, *(float(value) for pair in zip(sample.slip.longitudinal_m_s,
                                                          sample.slip.transverse_m_s,
                                                          strict=True) for value in pair))))
