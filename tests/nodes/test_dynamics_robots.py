"""dynamics_node simulating a fleet's robots on its one clock, in-process: each robot's
topics under its namespace with its own REP-105 frames, its own start pose and offsets, its
commands moving it alone; bad robot parameters refused by name."""

from __future__ import annotations

import pytest
from adapter_helpers import overrides
from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message

from omni_micro_common.errors import ParameterError
from omni_micro_control.controller_messages import move_trajectory
from omni_micro_control.servo_config import ServoCommand
from omni_micro_sim.dynamics_node import DynamicsNode
from omni_micro_sim.profile import move_profile

TWO_ROBOTS = dict(robots=['robot_0', 'robot_1'], robot_poses=[0.0, 0.0, 0.0, 0.02, 0.01, 0.5],
                  robot_wheel_offsets_rad=[0.0, 0.05, 0.03, 0.0, 0.0, 0.0])


def test_each_robot_publishes_under_its_namespace_and_moves_on_its_own_commands(context):
    node = DynamicsNode(context=context, parameter_overrides=overrides(**TWO_ROBOTS))
    try:
        sent: dict[str, list[bytes]] = {}
        for publisher in (node.clock_pub, *(pub for robot in node.robots
                                            for pub in robot.publishers)):
            publisher.publish = sent.setdefault(publisher.topic_name, []).append
        robot_0, robot_1 = node.robots
        assert robot_1.grid.simulator.params.wheel_offsets_rad == (0.0, 0.0, 0.0)
        assert robot_0.grid.simulator.params.wheel_offsets_rad == (0.0, 0.05, 0.03)
        profile = move_profile(1.0, robot_1.grid.limits)
        node._schedule_trajectory(robot_1, move_trajectory(ServoCommand(0.0, 0.0, profile),
                                                           profile, 'robot_1/base_link'))
        for _ in range(100):
            node._publish([robot.grid.advance() for robot in node.robots])
        assert len(sent['/clock']) == 100   # one clock for both
        first, last = (deserialize_message(sent['/robot_1/odom'][k], Odometry) for k in (0, -1))
        assert (last.header.frame_id, last.child_frame_id) == ('robot_1/odom',
                                                               'robot_1/base_link')
        # Its start pose (one tick into its move).
        assert first.pose.pose.position.x == pytest.approx(0.02, abs=1e-4)
        assert first.pose.pose.position.y == pytest.approx(0.01, abs=1e-4)
        assert last.pose.pose.position.x - first.pose.pose.position.x > 5e-3   # it drove
        still = [deserialize_message(data, Odometry).pose.pose.position
                 for data in sent['/robot_0/odom']]
        assert {(p.x, p.y) for p in still} == {(0.0, 0.0)}   # the other stood
        assert set(sent) == {'/clock', *(f'/robot_{k}/{topic}' for k in (0, 1) for topic in (
            'odom', 'joint_states', 'wheel_slip', 'odom_throttle', 'joint_states_throttle'))}
    finally:
        node.destroy_node()


def test_two_robots_touching_are_reported_once_naming_both(context, spy):
    """Two 9 mm discs 8 mm apart: a contact at the first tick, said once, latched."""
    node = DynamicsNode(context=context, parameter_overrides=overrides(
        robots=['robot_0', 'robot_1', 'robot_2'],
        robot_poses=[0.0, 0.0, 0.0, 0.008, 0.0, 0.0, 0.05, 0.0, 0.0]))
    try:
        said = spy(node.contact_pub).messages
        for _ in range(3):
            samples = [robot.grid.advance() for robot in node.robots]
            node._report_contacts(samples)
        assert len(said) == 1
        values = {item.key: item.value for item in said[0].values}
        assert said[0].level == DiagnosticStatus.ERROR and values['robots'] == 'robot_0,robot_1'
        assert float(values['gap_m']) == pytest.approx(0.008)
    finally:
        node.destroy_node()


@pytest.mark.parametrize('values, named', [
    (dict(robots=['robot_0', 'robot_0']), r"\['robot_0'\] named more than once"),
    (dict(robots=['robot-1']), "robots: each must be a plain name"),
    (dict(robots=['robot_0', 'robot_1'], robot_poses=[0.0, 0.0, 0.0]),
     'robot_poses: 3 finite numbers for each of the 2 robots'),
    (dict(robots=['robot_0'], robot_wheel_offsets_rad=[0.0, float('nan'), 0.0]),
     'robot_wheel_offsets_rad: 3 finite numbers'),
    (dict(robots=['robot_0'], lockstep_nodes=['robot_1/controller_node']),
     r"\['robot_1/controller_node'\] are in no robot's namespace"),
])
def test_bad_robot_parameters_are_refused_by_name(context, values, named):
    with pytest.raises(ParameterError, match=named):
        DynamicsNode(context=context, parameter_overrides=overrides(**values))
