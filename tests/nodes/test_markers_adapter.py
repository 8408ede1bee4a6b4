"""markers_node in-process: it reads only once the recorder can have its arrays, draws by
simulated time whatever the rate or order of its inputs, reads each capture from the topic the
controller reads, and refuses what it cannot draw, naming the value."""

from __future__ import annotations

import math
import time

import pytest
from adapter_helpers import assert_reads_input_only_once_matched, overrides
from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from visualization_msgs.msg import MarkerArray

from omni_micro_common.conventions import stamp_ns
from omni_micro_common.qos import DATA_QOS
from omni_micro_common.tick_messages import odometry_template, tick_templates
from omni_micro_vision import markers_node
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.markers_node import MarkersNode


def test_markers_node_reads_odometry_only_once_the_recorders_markers_reader_is_matched(
        context):
    """An array sent before would be lost to the bag (reliable, volatile): beside two busy
    processes a recorded servo run's bag once lacked the first 3.4 s of arrays, the recorder
    having matched the writer but not the writer the recorder."""
    assert_reads_input_only_once_matched(
        context, MarkersNode(context=context, parameter_overrides=overrides(
            markers_readers=['bag_recorder'])), 'bag_recorder',
        lambda recorder: recorder.create_subscription(MarkerArray, '/markers', lambda msg: None,
                                                      DATA_QOS),
        input_topic='/odom_throttle')


def test_markers_node_refuses_a_turned_field_that_is_not_a_number(context):
    with pytest.raises(CameraConfigError, match=r'macro\.yaw_rad'):
        MarkersNode(context=context, parameter_overrides=overrides(macro__yaw_rad=math.nan))


@pytest.mark.parametrize('colour', [[1.0, 0.5, 0.0], [1.0, 0.5, 0.0, 1.5], [math.nan] * 4])
def test_markers_node_refuses_a_robot_colour_that_is_not_rgba_in_0_1(context, colour):
    with pytest.raises(CameraConfigError, match=r'robot\.colour must be four numbers in \[0, 1\]'):
        MarkersNode(context=context, parameter_overrides=overrides(robot__colour=colour))


def _arrays_drawn(context, spy, period_ticks: int) -> list[tuple[int, bool]]:
    """(stamp in ns, whether it holds the camera fields) of each array markers_node publishes
    from 3 s of odometry, one sample in ``period_ticks`` of the 20 ms grid."""
    node = MarkersNode(context=context, parameter_overrides=overrides(
        publish_period_s=0.1, refresh_period_s=1.0))
    try:
        sent = spy(node.publisher)
        odometry = odometry_template()
        for tick in range(period_ticks, 151, period_ticks):
            at_ns = tick * 20_000_000
            node._on_odometry(odometry.encode((at_ns // 10**9, at_ns % 10**9,
                                               tick * 1e-5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)))
        node.finish()
        arrays = [deserialize_message(data, MarkerArray).markers for data in sent.messages]
        return [(stamp_ns(markers[0].header.stamp), any(m.ns == 'fields' for m in markers))
                for markers in arrays]
    finally:
        node.destroy_node()


def test_markers_node_draws_by_simulated_time_whatever_the_rate_of_its_odometry(context, spy):
    throttled = _arrays_drawn(context, spy, 5)  # /odom_throttle, as dynamics_node sends it
    every_tick = _arrays_drawn(context, spy, 1)  # a robot's /odom remapped to it
    # One array per 0.1 s from 0.1 s on (and the first sample's at 0.02 s at full rate), the
    # camera fields with the first and then once a second.
    assert throttled == [(k * 100_000_000, k == 1 or k % 10 == 0) for k in range(1, 31)]
    assert every_tick == [(20_000_000, True)] + [(k * 100_000_000, k % 10 == 0)
                                                 for k in range(1, 31)]


def _arrays_with_wheels(context, spy, wheels_late_by_ticks: int,
                        wheels_stop_at_tick: int = 151) -> tuple[int, list[bytes]]:
    """How many arrays markers_node publishes before it is stopped, and all it publishes, from
    3 s of odometry, joint states and slip at every tick of a 20 ms grid: the wheel streams
    (which have a publisher) delivered ``wheels_late_by_ticks`` after the odometry of their
    tick, as a sample resent by the reliable protocol is, and none from the tick
    ``wheels_stop_at_tick`` on; each steering and slip its tick's own."""
    node = MarkersNode(context=context, parameter_overrides=overrides(
        publish_period_s=0.1, refresh_period_s=1.0))
    robot = Node('wheel_writer', context=context)
    try:
        for topic in ('/wheel_slip', '/joint_states_throttle'):
            robot.create_publisher(JointState, topic, DATA_QOS)
        deadline = time.monotonic() + 10.0
        while not all(reader.get_publisher_count() for reader in node.subscriptions
                      if reader.topic_name in ('/wheel_slip', '/joint_states_throttle')):
            assert time.monotonic() < deadline, 'the wheel readers never saw their writers'
            time.sleep(0.01)
        sent = spy(node.publisher)
        templates = tick_templates('odom', 'base_link')
        deliveries = []
        for tick in range(151):
            sec, nanosec = divmod(tick * 20_000_000, 10**9)
            deliveries.append((tick, node._on_odometry, templates.odometry.encode(
                (sec, nanosec, tick * 1e-5, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0))))
            if tick >= wheels_stop_at_tick:
                continue
            late = tick + wheels_late_by_ticks
            deliveries.append((late, node._on_joint_state, templates.joint_state.encode(
                (sec, nanosec, 0.01 * tick, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0))))
            deliveries.append((late, node._on_slip, templates.slip.encode(
                (sec, nanosec, *[1e-4 * tick] * 6))))
        for _, deliver, data in sorted(deliveries, key=lambda delivery: delivery[0]):
            deliver(data)
        drawn_live = len(sent.messages)
        node.finish()
        return drawn_live, list(sent.messages)
    finally:
        robot.destroy_node()
        node.destroy_node()


def test_markers_node_draws_each_arrays_wheels_and_slip_whatever_the_order_they_arrive_in(
        context, spy, monkeypatch):
    """A composed images run once gave other /markers than the same seed in separate
    processes: from 0.6 s the wheels and slip arrows of arrays were of earlier samples, which
    reached the node after the odometry two arrays later."""
    _, in_order = _arrays_with_wheels(context, spy, 0)
    assert len(in_order) == 31 and len(set(in_order)) == 31
    # 0.3 s late, more than the two arrays the drawing lags the odometry by.
    assert _arrays_with_wheels(context, spy, 15)[1] == in_order
    # What waiting for the streams changes: drawn without, those arrays have other wheels.
    monkeypatch.setattr(markers_node, 'MAX_HELD_ARRAYS', 0)
    assert _arrays_with_wheels(context, spy, 15)[1] != in_order


def test_markers_node_draws_on_when_a_wheel_stream_falls_far_behind(context, spy, monkeypatch):
    """A publisher that went quiet holds the drawing MAX_HELD_ARRAYS arrays, not for good."""
    monkeypatch.setattr(markers_node, 'MAX_HELD_ARRAYS', 3)
    # The wheel streams stop at 0.5 s: waiting for them would have drawn 6 arrays (0 to 0.5 s)
    # of the 31 due; it draws all but the two the drawing lags by and the three it holds.
    drawn_live, drawn = _arrays_with_wheels(context, spy, 0, wheels_stop_at_tick=26)
    assert (drawn_live, len(drawn)) == (31 - 2 - 3, 31)


def _capture_with_covariance(x_m: float, at_s: float,
                             variance: float) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.stamp.sec = int(at_s)
    msg.header.stamp.nanosec = round(at_s % 1 * 1e9)
    msg.pose.pose.position.x = x_m
    msg.pose.covariance[0] = msg.pose.covariance[7] = variance
    return msg


def test_markers_node_reads_each_capture_from_one_topic_as_the_controller_does(context, spy):
    """With covariance (the default) the captures come from pose_with_covariance alone, drawn
    with their circle; a covariance that is not one is not drawn, and the node goes on."""
    node = MarkersNode(context=context)
    try:
        readers = {sub.topic_name: sub for sub in node.subscriptions}
        assert '/camera/macro/pose_with_covariance' in readers
        assert '/camera/macro/pose' not in readers and '/camera/micro/pose' not in readers
        sent = spy(node.publisher)
        readers['/camera/macro/pose_with_covariance'].callback(
            _capture_with_covariance(0.01, 0.05, 1e-10))
        readers['/camera/macro/pose_with_covariance'].callback(
            _capture_with_covariance(0.02, 0.06, -1.0))
        odometry = odometry_template()
        for tick in range(5, 31, 5):
            at_ns = tick * 20_000_000
            node._on_odometry(odometry.encode((at_ns // 10**9, at_ns % 10**9, 0.0, 0.0, 0.0,
                                               1.0, 0.0, 0.0, 0.0)))
        node.finish()
        drawn = [marker for data in sent.messages
                 for marker in deserialize_message(data, MarkerArray).markers]
        (points,) = {tuple((p.x, p.y) for p in m.points) for m in drawn
                     if m.ns == 'captures/macro'}
        assert points == ((0.01, 0.0),)
        (circle,) = {m.scale.x for m in drawn if m.ns == 'micro/capture_uncertainty/macro'}
        assert circle == pytest.approx(2 * 1e-5 * math.sqrt(-2 * math.log(0.05)), rel=1e-6)
    finally:
        node.destroy_node()
    bare = MarkersNode(context=context, parameter_overrides=overrides(
        capture_uncertainty='fixed'))
    try:
        topics = {sub.topic_name for sub in bare.subscriptions}
        assert {'/camera/macro/pose', '/camera/micro/pose'} <= topics
        assert not any(topic.endswith('pose_with_covariance') for topic in topics)
    finally:
        bare.destroy_node()
    with pytest.raises(CameraConfigError, match=r"capture_uncertainty .* got 'guessed'"):
        MarkersNode(context=context, parameter_overrides=overrides(
            capture_uncertainty='guessed'))


@pytest.mark.parametrize(('values', 'named'), [
    ({'publish_period_s': 0.0}, 'publish_period_s'),
    ({'refresh_period_s': math.inf}, 'refresh_period_s'),
    ({'publish_period_s': 0.3, 'refresh_period_s': 1.0}, 'whole multiple'),
])
def test_markers_node_refuses_periods_it_cannot_keep(context, values, named):
    with pytest.raises(CameraConfigError, match=named):
        MarkersNode(context=context, parameter_overrides=overrides(**values))
