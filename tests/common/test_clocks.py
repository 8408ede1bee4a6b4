"""Stamps on different clocks (omni_micro_common.clocks), and the nodes that meet them: a
capture or a trajectory from another clock is named with both clocks and what to set, never
waited for; the simulated robot can stamp the wall clock, as a real driver beside it does."""

import time

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from omni_micro_common.clocks import CLOCK_MISMATCH_S, clock_mismatch, describe_clock
from omni_micro_common.conventions import JOINT_NAMES
from omni_micro_control.controller_node import ControllerNode
from omni_micro_sim.dynamics_node import DynamicsNode
from omni_micro_sim.errors import ParameterError

WALL_S = 1_796_190_000.0   # 2026-12-02


def test_stamps_are_named_by_their_clock_and_a_mismatch_says_what_to_set():
    assert describe_clock(12.5) == '12.500 s (a clock from 0: simulated time)'
    assert describe_clock(WALL_S).endswith('(the wall clock, 2026-12-02 05:40:00 UTC)')
    assert clock_mismatch('a capture', 12.5, 'the robot', 12.5 + CLOCK_MISMATCH_S) is None
    wall_on_simulated = clock_mismatch('a capture', WALL_S, 'the robot', 12.5)
    assert wall_on_simulated is not None
    assert wall_on_simulated.startswith('a capture is stamped 1796190000.000 s (the wall clock')
    assert 'but the robot runs on 12.500 s (a clock from 0' in wall_on_simulated
    assert 'run with --camera external or --robot external' in wall_on_simulated
    simulated_on_wall = clock_mismatch('a trajectory', 3.0, 'this robot', WALL_S)
    assert simulated_on_wall is not None and 'stamp_origin: wall' in simulated_on_wall
    hours = clock_mismatch('a capture', WALL_S + 7200, 'the robot', WALL_S)
    assert hours is not None and hours.endswith("the clocks differ by 2.00 h: synchronise the "
                                                "machines' clocks (chrony, PTP)")


def test_the_controller_loses_a_goal_at_the_first_capture_from_another_clock(context):
    node = ControllerNode(context=context)
    try:
        statuses: list = []
        node.status_pub.publish = statuses.append
        wheels = JointState(name=list(JOINT_NAMES), position=[0.0] * 4, velocity=[0.0] * 4)
        wheels.header.stamp.sec = 5
        node._on_joint_state(serialize_message(wheels))
        from geometry_msgs.msg import PoseStamped

        goal = PoseStamped()
        goal.header.frame_id = 'platform'
        goal.pose.position.x = 0.01
        node._on_goal(goal)
        capture = PoseWithCovarianceStamped()
        capture.header.frame_id = 'platform'
        capture.header.stamp.sec = int(WALL_S)
        capture.pose.pose.orientation.w = 1.0
        capture.pose.covariance[0] = capture.pose.covariance[7] = 1e-12
        capture.pose.covariance[35] = 1e-6
        node.captures.on_capture_with_covariance(capture, 'macro')
        said = [(s.message, {v.key: v.value for v in s.values}) for s in statuses]
        assert said[-2][0] == 'clock mismatch'
        assert said[-1][0] == 'lost'
        reason = said[-1][1]['reason']
        assert reason.startswith('a macro capture is stamped 1796190000.000 s (the wall clock')
        assert 'but the robot runs on 5.000 s (a clock from 0: simulated time)' in reason
    finally:
        node.destroy_node()


def overrides(**values: object) -> list[Parameter]:
    return [Parameter(name, value=value) for name, value in values.items()]


def test_the_simulated_robot_stamps_the_wall_clock_from_when_time_starts(context):
    with pytest.raises(ParameterError, match='stamp_origin wall needs real_time_factor 1'):
        DynamicsNode(context=context, parameter_overrides=overrides(stamp_origin='wall',
                                                                    real_time_factor=2.0))
    with pytest.raises(ParameterError, match=r"stamp_origin must be one of \['zero', 'wall'\]"):
        DynamicsNode(context=context, parameter_overrides=overrides(stamp_origin='gps'))
    node = DynamicsNode(context=context, parameter_overrides=overrides(stamp_origin='wall'))
    try:
        published: list[bytes] = []
        node.robots[0].joint_pub.publish = published.append
        before = time.time()
        for _ in range(50):
            node._advance()
            time.sleep(0.002)
        assert published, 'time did not start'
        stamp = deserialize_message(published[-1], JointState).header.stamp
        assert before - 1.0 < stamp.sec + stamp.nanosec * 1e-9 < time.time() + 1.0
        # A trajectory stamped on the wall clock is on its clock; one from 0 is refused.
        move = JointTrajectory(joint_names=list(JOINT_NAMES), points=[JointTrajectoryPoint(
            positions=[0.0] * 4, velocities=[0.0] * 4)])
        move.header.stamp.sec = 3
        logged: list[str] = []
        node.get_logger().error = lambda message, **_: logged.append(message)
        node._schedule_trajectory(node.robots[0], move)
        assert logged and logged[-1].startswith('rejected: a /wheel_trajectory is stamped '
                                                '3.000 s (a clock from 0: simulated time) but '
                                                'this robot runs on ')
        assert node.grid.pending is None
    finally:
        node.destroy_node()
