"""controller_node's ``~/cancel`` service (std_srvs/Trigger), called as any client calls it: the
goal under way ends ``cancelled``, the robot is told to stop, and no move follows. A fleet's
guard on the bench stops every robot so."""

from __future__ import annotations

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from omni_micro_common.conventions import JOINT_NAMES, CaptureUncertainty
from omni_micro_control.controller_node import ControllerNode
from omni_micro_vision.capture_messages import capture_pose, with_uncertainty

UNCERTAINTY = CaptureUncertainty(0.1e-6, 0.1e-6, 1e-4)


def capture(node: ControllerNode, nanosec: int, x_m: float, in_motion: bool = False) -> None:
    node.captures.on_capture_with_covariance(
        with_uncertainty(capture_pose(0, nanosec, 'platform', x_m, 0.0, 0.0), UNCERTAINTY),
        camera='micro', in_motion=in_motion)


def call_cancel(context, node: ControllerNode) -> Trigger.Response:
    client_node = rclpy.create_node('guard', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    executor.add_node(client_node)
    try:
        client = client_node.create_client(Trigger, '/controller_node/cancel')
        assert client.wait_for_service(timeout_sec=10.0)
        future = client.call_async(Trigger.Request())
        executor.spin_until_future_complete(future, timeout_sec=10.0)
        assert future.done(), 'no answer from /controller_node/cancel within 10 s'
        return future.result()
    finally:
        executor.shutdown()
        client_node.destroy_node()


def test_a_rolling_robots_goal_cancelled_on_request_ends_and_no_move_follows(context, spy):
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('mode', value='servo'), Parameter('goal_m', value=[0.001, 0.0]),
        Parameter('captures_per_stop', value=1)])
    try:
        statuses = spy(node.status_pub)
        trajectories = spy(node.trajectory_pub)
        still = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                           velocity=[0.0] * len(JOINT_NAMES))
        still.header.stamp.nanosec = 200_000_000
        node._on_joint_state(serialize_message(still))
        capture(node, 200_000_000, 0.0)
        (rolling,) = trajectories.messages
        assert rolling.points and statuses.messages[-1].message == 'moving'

        answer = call_cancel(context, node)

        assert answer.success and answer.message == 'cancelled; the robot told to stop'
        ended = statuses.messages[-1]
        assert ended.message == 'cancelled'
        assert {v.key: v.value for v in ended.values}['reason'] == 'cancelled on request'
        stop = trajectories.messages[-1]
        assert stop is not rolling and stop.points == []   # an empty trajectory: stop now
        # The captures of the robot ramping down, rolling or still, decide nothing more.
        capture(node, 300_000_000, 5e-5, in_motion=True)
        capture(node, 400_000_000, 6e-5)
        assert len(trajectories.messages) == 2
        # Asked again: nothing under way, the robot told to stop all the same.
        again = call_cancel(context, node)
        assert again.success and again.message == 'no goal under way; the robot told to stop'
        assert statuses.messages[-1] is ended and trajectories.messages[-1].points == []
    finally:
        node.destroy_node()
