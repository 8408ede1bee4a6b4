"""bag_recorder and the viewer in-process: bags written readable, on simulated time or the wall
clock, every robot's streams counted, and what cannot be recorded (or served) refused."""

from __future__ import annotations

import time

import pytest
from adapter_helpers import overrides
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from visualization_msgs.msg import Marker, MarkerArray

from omni_micro_common.errors import ParameterError
from omni_micro_common.lockstep import Ack
from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.recorder_node import BagRecorder
from omni_micro_tools.viewer_node import Viewer


def test_bag_recorder_writes_what_it_receives_into_a_readable_bag(context, tmp_path):
    bag = tmp_path / 'bag'
    node = BagRecorder(context=context, parameter_overrides=overrides(
        bag=str(bag), topics=['/odom']))
    odometry = Odometry()
    odometry.header.stamp.sec = 3
    odometry.pose.pose.position.x = 0.0123
    node._writer_of('/odom')(serialize_message(odometry))
    node.close()
    node.destroy_node()
    (odom,) = read_bag(bag).messages['/odom']
    assert odom.pose.pose.position.x == 0.0123 and odom.header.stamp.sec == 3


def test_bag_recorder_keeps_logging_by_simulated_time_when_a_clock_of_another_kind_comes(
        context, tmp_path, monkeypatch):
    """One /clock message on the wall clock in a simulated run (another graph's on this domain)
    would place every later message at its time, past the bag's end: the recorder says so once
    and goes on logging by simulated time."""
    bag = tmp_path / 'bag'
    node = BagRecorder(context=context, parameter_overrides=overrides(
        bag=str(bag), topics=['/odom']))
    warnings: list[str] = []
    logger = node.get_logger()
    monkeypatch.setattr(logger, 'warning', lambda message, **kwargs: warnings.append(message))
    for sec in (1, int(time.time()), int(time.time()) + 1, 2):
        clock = Clock()
        clock.clock.sec = sec
        node._on_clock(serialize_message(clock))
    odometry = Odometry()
    odometry.header.stamp.sec = 2
    node._writer_of('/odom')(serialize_message(odometry))
    node.close()
    node.destroy_node()
    assert read_bag(bag).timestamps['/odom'] == [2_000_000_000]
    assert len(warnings) == 1 and 'another graph publishes /clock' in warnings[0]
    assert '(the wall clock' in warnings[0]


def test_bag_recorder_on_the_bench_logs_on_the_wall_clock_with_the_drivers_images(context,
                                                                                  tmp_path):
    """A real robot has no /clock: each message is logged when it came, by the system clock,
    and a status said at time 0 (before the robot's first state) stays where it came, not
    before the run; a driver's images, on any topic, are recorded with their CameraInfo."""
    from sensor_msgs.msg import Image

    bag = tmp_path / 'bag'
    node = BagRecorder(context=context, parameter_overrides=[
        Parameter('bag', value=str(bag)), Parameter('topics', value=['/controller/status']),
        Parameter('log_clock', value='wall'),
        Parameter('driver_images', value=['/bench/camera/image_raw'])])
    assert {'/bench/camera/image_raw', '/bench/camera/camera_info'} <= set(node.topics)
    before = time.time_ns()
    node._writer_of('/controller/status')(serialize_message(DiagnosticStatus(
        message='idle', values=[KeyValue(key='status_time_s', value='0.0')])))
    image = Image(height=1, width=2, encoding='mono8', step=2, data=b'\x01\x02')
    image.header.stamp.sec = before // 10**9
    node._writer_of('/bench/camera/image_raw')(serialize_message(image))
    node.close()
    node.destroy_node()
    data = read_bag(bag)
    (status_at,) = data.timestamps['/controller/status']
    assert before <= status_at <= time.time_ns()
    assert data.messages['/bench/camera/image_raw'][0].data.tobytes() == b'\x01\x02'


def test_bag_recorder_in_the_lockstep_counts_a_frame_written_once_its_camera_info_is(
        context, tmp_path, monkeypatch):
    """In the lockstep the robot waits for the recorder as for the tracker: for a frame's image
    and its CameraInfo, of every camera (one CameraInfo lost from a bag made the same seed give
    another file)."""
    from sensor_msgs.msg import CameraInfo, Image

    from omni_micro_tools.topics import IMAGE_TOPICS

    node = BagRecorder(context=context, parameter_overrides=[
        Parameter('bag', value=str(tmp_path / 'bag')), Parameter('topics', value=[
            '/odom', *IMAGE_TOPICS]), Parameter('lockstep_frames', value=True)])
    reported: list[Ack] = []
    assert node.lockstep is not None
    monkeypatch.setattr(node.lockstep, 'report', reported.append)
    streams = (('/camera/macro/image_raw', Image), ('/camera/micro/image_raw', Image),
               ('/camera/micro/camera_info', CameraInfo),
               ('/camera/macro/camera_info', CameraInfo))
    for index, (topic, kind) in enumerate(streams):
        message = kind()
        message.header.stamp.nanosec = 33_333_333
        node._writer_of(topic)(serialize_message(message))
        # Written up to frame 1 only once all four streams have it; before, nothing of it.
        assert reported[-1].frame_handled_ns == (33_333_333 if index == 3 else -1)
    node.close()
    node.destroy_node()


@pytest.mark.parametrize(('values', 'named'), [
    ({}, 'bag must name'),
    ({'bag': 'x', 'log_clock': 'sundial'}, "'sundial'"),
    ({'bag': 'x', 'driver_images': ['camera/image_raw']}, 'camera/image_raw'),
    ({'bag': 'x', 'topics': ['/nope']}, "'/nope'"),
    # A fleet robot's clock is the graph's; a namespace is one plain name.
    ({'bag': 'x', 'topics': ['/robot_1/clock']}, "'/robot_1/clock'"),
    ({'bag': 'x', 'topics': ['/robot 1/odom']}, "'/robot 1/odom'"),
    ({'bag': 'x', 'storage': 'zip'}, "'zip'"),
])
def test_bag_recorder_refuses_what_it_cannot_record(context, tmp_path, values, named):
    if 'bag' in values:
        values = {**values, 'bag': str(tmp_path / values['bag'])}
    with pytest.raises(ParameterError, match=named):
        BagRecorder(context=context, parameter_overrides=overrides(**values))
    assert not (tmp_path / 'x').exists()


def test_bag_recorder_records_each_robot_of_a_fleet_and_says_how_far_it_has_all(
        context, tmp_path):
    """Each robot's per-tick streams count: it has everything up to the oldest of them."""
    topics = ['/clock', *(f'/robot_{k}/{stream}' for k in (0, 1)
                          for stream in ('odom', 'joint_states', 'wheel_slip', 'goal_pose'))]
    node = BagRecorder(context=context, parameter_overrides=overrides(
        bag=str(tmp_path / 'bag'), topics=topics))
    try:
        assert {sub.topic_name for sub in node.subscriptions} == set(topics)
        assert sorted(node._received_stamps_ns) == sorted(t for t in topics if 'goal' not in t)
        for topic in node._received_stamps_ns:
            kind = Clock if topic == '/clock' else Odometry if 'odom' in topic else JointState
            message = kind()
            stamp = message.clock if kind is Clock else message.header.stamp
            stamp.sec = 0 if topic == '/robot_1/wheel_slip' else 2
            node._writer_of(topic)(serialize_message(message))
        assert min(node._received_stamps_ns.values()) == 0   # robot 1's slip is behind
    finally:
        node.close()
        node.destroy_node()
    assert sorted(read_bag(tmp_path / 'bag').timestamps) == sorted(topics)


@pytest.mark.parametrize('log_clock', ['sim', 'wall'])
def test_bag_recorder_has_received_up_to_the_markers_drawn_behind_the_odometry(
        context, tmp_path, log_clock):
    """On the simulated clock the markers' arrays, drawn behind the odometry, count in how far
    the recorder has everything (what whoever stops the graph waits for); an empty array says
    nothing. On the wall clock (the bench) they do not count."""
    topics = ['/clock', '/odom', '/joint_states', '/wheel_slip', '/markers']
    node = BagRecorder(context=context, parameter_overrides=overrides(
        bag=str(tmp_path / 'bag'), topics=topics, log_clock=log_clock))

    def markers_at(sec: int, nanosec: int, empty: bool = False) -> None:
        array = MarkerArray(markers=[] if empty else [Marker(), Marker()])
        for marker in array.markers:
            marker.header.stamp.sec, marker.header.stamp.nanosec = sec, nanosec
        node._writer_of('/markers')(serialize_message(array))
    try:
        for topic in topics[:4]:
            kind = Clock if topic == '/clock' else Odometry if topic == '/odom' else JointState
            message = kind()
            (message.clock if kind is Clock else message.header.stamp).sec = 15
            node._writer_of(topic)(serialize_message(message))
        markers_at(14, 500_000_000)
        markers_at(0, 0, empty=True)
        received_ns = min(node._received_stamps_ns.values())
        assert received_ns == (14_500_000_000 if log_clock == 'sim' else 15_000_000_000)
        markers_at(15, 200_000_000)
        assert min(node._received_stamps_ns.values()) == 15_000_000_000
    finally:
        node.close()
        node.destroy_node()


def test_bag_recorder_never_records_over_an_existing_folder(context, tmp_path):
    (tmp_path / 'mine').mkdir()
    with pytest.raises(ParameterError, match='exists already'):
        BagRecorder(context=context, parameter_overrides=overrides(bag=str(tmp_path / 'mine')))


def test_viewer_refuses_a_port_out_of_range(context):
    with pytest.raises(ParameterError, match='70000'):
        Viewer(context=context, parameter_overrides=overrides(port=70000))
