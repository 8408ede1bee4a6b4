"""dynamics_node in-process: its parameters checked at start and at run time, the slip and
the throttled streams on their ticks, time started only once the awaited readers are matched."""

from __future__ import annotations

import math
import re
import time

import pytest
import rclpy
from adapter_helpers import overrides
from nav_msgs.msg import Odometry
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from omni_micro_common.errors import ParameterError
from omni_micro_common.qos import DATA_QOS
from omni_micro_common.reader_matching import reader_census
from omni_micro_sim.dynamics_node import DynamicsNode


def test_dynamics_node_refuses_a_bad_factor_at_start_and_at_run_time(context):
    with pytest.raises(ParameterError, match='real_time_factor'):
        DynamicsNode(context=context, parameter_overrides=overrides(real_time_factor=0.0))
    node = DynamicsNode(context=context, parameter_overrides=overrides(real_time_factor=2.0))
    try:
        refused = node.set_parameters([Parameter('real_time_factor', value=-1.0)])[0]
        assert not refused.successful and '-1.0' in refused.reason
        assert node.real_time_factor == 2.0
        # .inf (as fast as the lockstep allows) needs nodes to wait for.
        refused = node.set_parameters([Parameter('real_time_factor', value=math.inf)])[0]
        assert not refused.successful and 'lockstep_nodes' in refused.reason
        assert node.set_parameters([Parameter('real_time_factor', value=5.0)])[0].successful
        assert node.real_time_factor == 5.0
    finally:
        node.destroy_node()


def test_dynamics_node_refuses_a_malformed_initial_pose(context):
    with pytest.raises(ParameterError, match='initial_pose'):
        DynamicsNode(context=context, parameter_overrides=overrides(initial_pose=[0.0, 1.0]))


@pytest.mark.parametrize('name, value', [
    ('robot.steering.backlash_rad', -0.01), ('robot.steering.motor_speed_rad_s', 0.0),
    ('robot.steering.contact_radius_m', math.nan), ('robot.center_of_mass_m', [0.01, 0.0])])
def test_dynamics_node_refuses_bad_steering_parameters_naming_them(context, name, value):
    with pytest.raises(ParameterError, match=name.removeprefix('robot.').split('.')[-1]):
        DynamicsNode(context=context, parameter_overrides=[Parameter(name, value=value)])


@pytest.mark.parametrize('name', ['wheel_slip_every', 'throttle_every'])
@pytest.mark.parametrize('value', [0, -1, 2.5, True])
def test_dynamics_node_refuses_a_rate_that_is_not_a_whole_number_of_ticks(context, name, value):
    with pytest.raises((ParameterError, InvalidParameterTypeException), match=name):
        DynamicsNode(context=context, parameter_overrides=overrides(**{name: value}))


def test_dynamics_node_publishes_the_slip_on_one_tick_in_wheel_slip_every(context):
    node = DynamicsNode(context=context, parameter_overrides=overrides(wheel_slip_every=3))
    try:
        published: list[bytes] = []
        robot = node.robots[0]
        robot.slip_pub.publish = published.append
        robot.odom_pub.publish = lambda data: None
        for _ in range(9):
            node._publish([node.grid.advance()])
        assert len(published) == 3
    finally:
        node.destroy_node()


def test_dynamics_node_takes_the_steering_from_its_parameters(context):
    node = DynamicsNode(context=context, parameter_overrides=overrides(
        robot__steering__instantaneous=False, robot__steering__backlash_rad=0.02))
    try:
        steering = node.grid.simulator.params.steering
        assert not steering.instantaneous and steering.backlash_rad == 0.02
        assert node.get_parameter('robot.steering.gear_ratio').value == 3.0
    finally:
        node.destroy_node()


def test_dynamics_node_throttles_odometry_and_joints_for_who_only_watches(context):
    node = DynamicsNode(context=context, parameter_overrides=overrides(throttle_every=4))
    try:
        sent: dict[str, list[bytes]] = {}
        robot = node.robots[0]
        for publisher in (robot.odom_pub, robot.joint_pub, robot.odom_throttle_pub,
                          robot.joint_throttle_pub):
            publisher.publish = sent.setdefault(publisher.topic_name, []).append
        for _ in range(12):
            node._publish([node.grid.advance()])
        # The same messages, those of ticks 4, 8 and 12.
        assert sent['/odom_throttle'] == sent['/odom'][3::4]
        assert sent['/joint_states_throttle'] == sent['/joint_states'][3::4]
        assert len(set(sent['/odom_throttle'])) == 3
    finally:
        node.destroy_node()


def test_dynamics_node_starts_time_only_once_the_recorders_readers_are_matched(context):
    """The recorder says "recording" once its readers see the publishers, which is not that the
    publishers have matched its readers: a run's bag once lacked its first odometry."""
    node = DynamicsNode(context=context, parameter_overrides=overrides(
        awaited_readers=[f'bag_recorder:{topic}' for topic in
                         ('/clock', '/odom', '/joint_states', '/wheel_slip')],
        real_time_factor=100.0))
    recorder = rclpy.create_node('bag_recorder', context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        executor.add_node(node)
        for _ in range(4):
            executor.spin_once(timeout_sec=0.05)
        assert node.grid.tick == 0
        waiting = node._waiting_for()
        assert "matching bag_recorder's reader of /clock" in waiting
        # Said with what the node knows: no reader seen by name, none matched.
        assert '/clock: the graph shows 0 reader(s), its writer matched 0' in waiting
        for topic, kind in (('/clock', Clock), ('/odom', Odometry), ('/joint_states', JointState),
                            ('/wheel_slip', JointState)):
            recorder.create_subscription(kind, topic, lambda msg: None, DATA_QOS)
        deadline = time.monotonic() + 10.0
        while node.grid.tick == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert node.grid.tick > 0
        assert reader_census(node, node._publishers_of['/odom']) == \
            '/odom: the graph shows 1 reader(s) (bag_recorder), its writer matched 1'
    finally:
        executor.shutdown()
        recorder.destroy_node()
        node.destroy_node()


@pytest.mark.parametrize('entries, words', [
    (['markers_node'], 'each entry must be NODE:/TOPIC'),
    (['markers_node:odom'], 'each entry must be NODE:/TOPIC'),
    (['markers_node:/markers'], "markers_node reads ['/markers'], which this node does not "
                                'publish'),
])
def test_dynamics_node_refuses_awaited_readers_it_cannot_wait_for(context, entries, words):
    with pytest.raises(ParameterError, match=re.escape(words)):
        DynamicsNode(context=context, parameter_overrides=overrides(awaited_readers=entries))
