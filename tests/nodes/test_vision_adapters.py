"""The camera nodes in-process (vision_node, camera_node, tracker_node, markers_node): parameters
checked, inputs read only once their readers are matched, frames and captures turned into
messages and back, refusals that name the value."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
from adapter_helpers import assert_reads_input_only_once_matched, frame, overrides
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import CameraInfo, Image, JointState
from visualization_msgs.msg import MarkerArray

from omni_micro_common.conventions import quaternion_to_yaw, stamp_ns, yaw_to_quaternion
from omni_micro_common.qos import CAPTURE_QOS, DATA_QOS, IMAGE_QOS
from omni_micro_common.tick_messages import odometry_template, tick_templates
from omni_micro_sim.state import RobotState
from omni_micro_vision import markers_node
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.camera_node import CameraNode
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.markers_node import MarkersNode
from omni_micro_vision.rendering import Sensor, render
from omni_micro_vision.tracker_node import TrackerNode
from omni_micro_vision.vision_node import VisionNode


def test_vision_node_reads_odometry_only_once_the_capture_readers_are_matched(context):
    """The first captures come at time 0: one sent before markers_node's reader was matched was
    lost to it (reliable, volatile)."""
    def covariance_readers(markers: Node) -> None:
        for camera in ('macro', 'micro'):
            markers.create_subscription(PoseWithCovarianceStamped,
                                        f'/camera/{camera}/pose_with_covariance',
                                        lambda msg: None, CAPTURE_QOS)
    assert_reads_input_only_once_matched(
        context, VisionNode(context=context, parameter_overrides=overrides(
            covariance_readers=['markers_node'])), 'markers_node', covariance_readers)


def test_vision_node_lets_only_faults_change_while_it_runs(context):
    node = VisionNode(context=context)
    try:
        refused = node.set_parameters([Parameter('seed', value=3)])[0]
        assert not refused.successful and 'seed is fixed' in refused.reason
    finally:
        node.destroy_node()


def test_camera_node_renders_a_frame_of_the_odometry_stamped_with_its_time(context, spy):
    node = CameraNode(context=context, parameter_overrides=overrides(cameras=['macro']))
    try:
        images, infos = spy(node.streams[0].image_pub), spy(node.streams[0].info_pub)
        odometry = Odometry()
        odometry.pose.pose.position.x, odometry.pose.pose.position.y = 0.05, 0.0
        odometry.pose.pose.orientation.z, odometry.pose.pose.orientation.w = yaw_to_quaternion(
            0.0)
        for nanosec in (0, 20_000_000, 40_000_000):   # the 50 Hz grid: frames 0 and 1 (1/30 s)
            odometry.header.stamp.nanosec = nanosec
            node._on_odometry(serialize_message(odometry))   # raw, as it subscribes
        frames = [deserialize_message(data, Image) for data in images.messages]
        assert [m.header.stamp.nanosec for m in frames] == [0, round(1e9 / 30)]
        assert (frames[0].width, frames[0].height, frames[0].encoding) == (1280, 1024, 'mono8')
        assert frames[0].header.frame_id == 'macro_optical_frame'
        assert len(frames[0].data) == 1280 * 1024
        # The robot, at the field's centre, is drawn there: not the platform of the corner.
        pixels = np.frombuffer(frames[0].data, np.uint8).reshape(1024, 1280).astype(float)
        assert abs(pixels[462:562, 590:690].mean() - pixels[:100, :100].mean()) > 10
        infos = [deserialize_message(data, CameraInfo) for data in infos.messages]
        assert [(i.width, i.height, i.header.stamp.nanosec) for i in infos] == \
            [(1280, 1024, 0), (1280, 1024, round(1e9 / 30))]
        # A true CameraInfo, as image_pipeline reads it: a pinhole 0.3 m above the platform,
        # its pixels 117.19 um there, no distortion by default; the image's own frame.
        info = infos[0]
        assert info.header.frame_id == 'macro_optical_frame'
        assert info.distortion_model == 'plumb_bob' and list(info.d) == [0.0] * 5
        fx, fy = 0.3 / (0.15 / 1280), 0.3 / (0.15 / 1024)
        np.testing.assert_allclose(info.k, [fx, 0, 639.5, 0, fy, 511.5, 0, 0, 1], rtol=1e-12)
        np.testing.assert_allclose(info.p, [fx, 0, 639.5, 0, 0, fy, 511.5, 0, 0, 0, 1, 0],
                                   rtol=1e-12)
        assert list(info.r) == [1.0, 0, 0, 0, 1.0, 0, 0, 0, 1.0]
    finally:
        node.destroy_node()


def test_camera_node_reads_odometry_only_once_the_trackers_image_reader_is_matched(context):
    """A frame sent before would be lost to the tracker, and the lockstep would stand still."""
    assert_reads_input_only_once_matched(
        context, CameraNode(context=context, parameter_overrides=overrides(
            cameras=['macro'], image_readers=['tracker_node'])), 'tracker_node',
        lambda tracker: tracker.create_subscription(Image, '/camera/macro/image_raw',
                                                    lambda msg: None, IMAGE_QOS))


def test_tracker_node_reads_images_only_once_the_capture_readers_are_matched(context):
    """Its first capture comes three frames after time 0: one sent before markers_node's reader
    was matched would be lost to it (reliable, volatile), and the camera's frames, then the
    robot's clock, wait for the tracker's image readers."""
    def covariance_readers(markers: Node) -> None:
        markers.create_subscription(PoseWithCovarianceStamped,
                                    '/camera/macro/pose_with_covariance', lambda msg: None,
                                    CAPTURE_QOS)
    assert_reads_input_only_once_matched(
        context, TrackerNode(context=context, parameter_overrides=overrides(
            cameras=['macro'], covariance_readers=['markers_node'])), 'markers_node',
        covariance_readers, input_topic='/camera/macro/image_raw')


def test_tracker_node_reads_images_only_once_the_servos_motion_reader_is_matched(context):
    """A servo acts on the captures in motion: one sent before its reader is matched would be
    lost to it (reliable, volatile)."""
    assert_reads_input_only_once_matched(
        context, TrackerNode(context=context, parameter_overrides=overrides(
            cameras=['macro'], captures_in_motion=True, motion_readers=['controller_node'])),
        'controller_node',
        lambda servo: servo.create_subscription(PoseWithCovarianceStamped,
                                                '/camera/macro/pose_in_motion',
                                                lambda msg: None, CAPTURE_QOS),
        input_topic='/camera/macro/image_raw')


def test_a_fleet_tracker_waits_for_the_recorder_on_each_robots_captures_in_motion(context):
    """A reader outside every robot's namespace (the recorder) reads each robot's topics, and
    is waited for on each."""
    assert_reads_input_only_once_matched(
        context, TrackerNode(context=context, parameter_overrides=overrides(
            cameras=['macro'], robots=['robot_0'], captures_in_motion=True,
            motion_readers=['bag_recorder'])), 'bag_recorder',
        lambda recorder: recorder.create_subscription(
            PoseWithCovarianceStamped, '/robot_0/camera/macro/pose_in_motion', lambda msg: None,
            CAPTURE_QOS),
        input_topic='/camera/macro/image_raw')


def test_vision_node_reads_odometry_only_once_the_servos_motion_readers_are_matched(context):
    def motion_readers(servo: Node) -> None:
        for camera in ('macro', 'micro'):
            servo.create_subscription(PoseWithCovarianceStamped,
                                      f'/camera/{camera}/pose_in_motion', lambda msg: None,
                                      CAPTURE_QOS)
    assert_reads_input_only_once_matched(
        context, VisionNode(context=context, parameter_overrides=overrides(
            captures_in_motion=True, motion_readers=['controller_node'])), 'controller_node',
        motion_readers)


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


def test_tracker_node_refuses_odd_frames_and_camera_infos_and_keeps_serving(context, spy):
    """A message is never a reason to stop a node: a 0x0 frame before any CameraInfo once
    exited the node as 'an invalid parameter'; a CameraInfo with a NaN in K is refused too."""
    node = TrackerNode(context=context, parameter_overrides=overrides(cameras=['macro']))
    try:
        reader = node.readers[0]
        statuses = spy(reader.status_pub)
        reader.on_image(serialize_message(Image(height=0, width=0, encoding='mono8')))
        assert statuses.messages[-1].message == ('frame refused: image is 0 x 0, expected 1280 '
                                                 'x 1024')
        broken = CameraInfo(height=1024, width=1280)
        broken.k[0], broken.k[4], broken.k[8] = float('nan'), 1.0, 1.0
        reader.on_info(broken)
        assert reader.info_refusal is not None and 'must be finite' in reader.info_refusal
        pixels = render(DEFAULT_RIG.macro, Sensor(), RobotState(0.05, 0.0, 0.0),
                        np.random.default_rng(1))
        reader.on_image(serialize_message(frame(pixels, 0)[0]))
        assert statuses.messages[-1].message.startswith('frame refused: CameraInfo is not usable')
        reader.on_info(frame(pixels, 0)[1])     # an uncalibrated driver's: accepted again
        reader.on_image(serialize_message(frame(pixels, 1)[0]))
        assert statuses.messages[-1].message == 'moving'
    finally:
        node.destroy_node()


def test_camera_node_refuses_a_frame_rate_of_zero(context):
    with pytest.raises(CameraConfigError, match='frame_rate_hz'):
        CameraNode(context=context, parameter_overrides=overrides(frame_rate_hz=0.0))


def test_tracker_node_turns_frames_of_a_still_robot_into_captures_where_it_is(context, spy):
    node = TrackerNode(context=context, parameter_overrides=overrides(cameras=['macro']))
    try:
        reader = node.readers[0]
        captures, covariances = spy(reader.capture_pub), spy(reader.covariance_pub)
        statuses = spy(reader.status_pub)
        truth = RobotState(0.05, 0.01, 0.4)
        for index in range(4):
            pixels = render(DEFAULT_RIG.macro, Sensor(), truth, np.random.default_rng([5, index]))
            image, info = frame(pixels, index * 33_333_333)
            reader.on_info(info)
            reader.on_image(serialize_message(image))   # raw, as it subscribes
        # Three frames agree from the third on: a capture each, stamped with its frame.
        assert [c.header.stamp.nanosec for c in captures.messages] == [66_666_666, 99_999_999]
        for capture in captures.messages:
            position = capture.pose.position
            assert math.hypot(position.x - truth.x_m, position.y - truth.y_m) < 20e-6
            assert abs(quaternion_to_yaw(capture.pose.orientation.z,
                                         capture.pose.orientation.w) - truth.phi_rad) < 0.01
        assert len(covariances.messages) == 2 and covariances.messages[0].pose.covariance[0] > 0
        image, _ = frame(np.zeros((1024, 1280), dtype=np.uint8), 5 * 33_333_333)
        image.encoding = '32FC1'
        reader.on_image(serialize_message(image))
        assert "encoding '32FC1' is not one the tracker reads" in statuses.messages[-1].message
        reader.on_image(serialize_message(image)[:30])   # cut short: refused, named
        assert 'an image message' in statuses.messages[-1].message
        assert len(captures.messages) == 2
    finally:
        node.destroy_node()


def test_tracker_node_says_how_old_a_drivers_frames_come_and_nothing_of_simulated_ones(
        context, spy):
    """Frames stamped on the wall clock (a driver's) get their age measured and said in the
    status, with the topic; camera_node's, stamped from 0, get none."""
    node = TrackerNode(context=context, parameter_overrides=overrides(
        cameras=['macro'], **{'macro.image_topic': '/bench/camera/image_raw'}))
    try:
        reader = node.readers[0]
        statuses = spy(reader.status_pub)
        truth = RobotState(0.05, 0.01, 0.4)
        pixels = render(DEFAULT_RIG.macro, Sensor(), truth, np.random.default_rng(5))
        for index in range(6):
            image, info = frame(pixels, index * 33_333_333)
            reader.on_info(info)
            reader.on_image(serialize_message(image))
        assert all(not status.values for status in statuses.messages)
        now_ns = time.time_ns()
        for index in range(5):
            image, _ = frame(pixels, now_ns - 40_000_000 + index * 33_333_333)
            reader.on_image(serialize_message(image))
        said = {item.key: item.value for item in statuses.messages[-1].values}
        assert said['image_topic'] == '/bench/camera/image_raw'
        assert float(said['frame_age_s']) >= 0.040 - 0.002    # at least as late as stamped
        assert float(said['frame_rate_hz']) == pytest.approx(30.0, rel=1e-3)
        assert statuses.messages[-1].message == 'still: capturing'
    finally:
        node.destroy_node()


def test_tracker_node_refuses_an_unknown_camera_naming_it(context):
    with pytest.raises(CameraConfigError, match="'tele'"):
        TrackerNode(context=context, parameter_overrides=overrides(cameras=['macro', 'tele']))


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
