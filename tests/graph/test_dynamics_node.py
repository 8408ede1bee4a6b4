"""dynamics_node as a real process: its topics, parameters and wheel commands."""

import itertools
import math
from typing import Any

import pytest
from builtin_interfaces.msg import Duration
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from omni_micro_common.conventions import JOINT_NAMES, split_stamp
from omni_micro_sim import paper
from omni_micro_sim.open_loop import simulate_open_loop
from omni_micro_sim.profile import move_profile
from omni_micro_sim.wheel_trajectory import points_from_profile

QOS = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE)


def double(name, value):
    return Parameter(name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                     double_value=value))


def trajectory_msg(start_s, duration_s, steering_rad=0.0, joint_names=JOINT_NAMES):
    msg = JointTrajectory()
    msg.header.stamp.sec, msg.header.stamp.nanosec = split_stamp(start_s)
    msg.joint_names = list(joint_names)
    for point in points_from_profile(steering_rad, move_profile(duration_s)):
        sec, nanosec = split_stamp(point.time_from_start_s)
        msg.points.append(JointTrajectoryPoint(positions=list(point.positions),
                                               velocities=list(point.velocities),
                                               time_from_start=Duration(sec=sec,
                                                                        nanosec=nanosec)))
    return msg


@pytest.fixture
def robot(start_node, probe):
    process = start_node('omni_micro_sim', 'dynamics_node', 'real_time_factor:=4.0')
    seen: dict[str, list[Any]] = {'clock': [], 'odom': [], 'joints': [], 'slip': []}
    probe.node.create_subscription(Clock, '/clock', lambda m: seen['clock'].append(m), 10)
    probe.node.create_subscription(Odometry, '/odom', lambda m: seen['odom'].append(m), QOS)
    probe.node.create_subscription(JointState, '/joint_states',
                                   lambda m: seen['joints'].append(m), QOS)
    probe.node.create_subscription(JointState, '/wheel_slip', lambda m: seen['slip'].append(m),
                                   QOS)
    publisher = probe.node.create_publisher(JointTrajectory, '/wheel_trajectory', QOS)
    # Every stream heard from: each reader matches at its own pace (beside two busy processes
    # /wheel_slip's had nothing yet when /odom had six samples).
    probe.spin_until(lambda: len(seen['odom']) > 5 and all(seen.values())
                     and publisher.get_subscription_count() > 0,
                     30.0, 'every stream of dynamics_node')
    return process, seen, publisher


def test_publishes_clock_odometry_joint_states_and_slip(robot):
    _, seen, _ = robot
    odom = seen['odom'][-1]
    assert (odom.header.frame_id, odom.child_frame_id) == ('odom', 'base_link')
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in seen['odom']]
    assert all(b - a == pytest.approx(0.02) for a, b in itertools.pairwise(stamps))
    assert seen['clock'] and seen['joints'][-1].name == list(JOINT_NAMES)
    assert seen['slip'][-1].name == [f'wheel_{k}_{part}' for k in (1, 2, 3)
                                     for part in ('longitudinal', 'transverse')]
    assert odom.pose.pose.position.x == 0.0 and odom.pose.pose.orientation.w == 1.0


def test_parameters_come_from_the_package_file_and_bad_values_are_refused(robot, probe):
    get = probe.node.create_client(GetParameters, '/dynamics_node/get_parameters')
    values = probe.call(get, GetParameters.Request(
        names=['robot.wheel_offsets_rad', 'publish_period_s'])).values
    assert list(values[0].double_array_value) == pytest.approx(
        [math.radians(v) for v in paper.SECTION_353_OFFSETS_DEG])
    assert values[1].double_value == 0.02
    set_ = probe.node.create_client(SetParameters, '/dynamics_node/set_parameters')
    results = probe.call(set_, SetParameters.Request(parameters=[
        double('real_time_factor', -1.0)])).results
    assert not results[0].successful and 'real_time_factor' in results[0].reason
    results = probe.call(set_, SetParameters.Request(parameters=[
        double('robot.mass_kg', 1.0)])).results
    assert not results[0].successful


def test_a_move_runs_exactly_its_profile_in_simulated_time(robot, probe):
    _, seen, publisher = robot
    now = seen['odom'][-1].header.stamp
    start = now.sec + now.nanosec * 1e-9 + 0.5
    publisher.publish(trajectory_msg(start, 0.5))

    def finished():
        joints = seen['joints'][-1]
        return joints.position[2] > 4.3 and joints.velocity[2] == 0.0 and \
            abs(seen['odom'][-1].twist.twist.linear.x) < 1e-9

    probe.spin_until(finished, 30.0, 'the move to finish')
    assert seen['joints'][-1].position[1:] == pytest.approx([8.7 * 0.5] * 3, rel=1e-9)
    # Exactly the open-loop core's move: the node adds no error and no latency.
    reference = simulate_open_loop(paper.FIG8.robot(), 0.0, 0.5).final_state
    pose = seen['odom'][-1].pose.pose.position
    assert pose.x == pytest.approx(reference.x_m, abs=1e-9)
    assert pose.y == pytest.approx(reference.y_m, abs=1e-9)


def test_malformed_trajectory_is_rejected_and_the_robot_stays_put(robot, probe, tmp_path):
    _, seen, publisher = robot
    publisher.publish(trajectory_msg(0.0, 0.5, joint_names=['a', 'b', 'c', 'd']))
    count = len(seen['odom'])
    probe.spin_until(lambda: len(seen['odom']) > count + 25, 30.0, 'more odometry')
    assert seen['odom'][-1].pose.pose.position.x == 0.0
    assert list(seen['joints'][-1].velocity[1:]) == [0.0, 0.0, 0.0]
    probe.spin_until(lambda: 'rejected wheel trajectory' in
                     (tmp_path / 'dynamics_node.log').read_text(), 10.0, 'the rejection log')
