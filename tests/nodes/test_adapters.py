"""Every node adapter in-process: parameters checked at start and at run time, messages turned
into the plain modules' types and back, refusals that name the value."""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from visualization_msgs.msg import MarkerArray

from omni_micro_common.conventions import quaternion_to_yaw, stamp_ns, yaw_to_quaternion
from omni_micro_common.errors import ParameterError
from omni_micro_common.qos import CAPTURE_QOS, DATA_QOS, IMAGE_QOS
from omni_micro_common.tick_messages import odometry_template
from omni_micro_control.controller_node import ControllerNode
from omni_micro_control.errors import ControllerConfigError
from omni_micro_sim.dynamics_node import DynamicsNode
from omni_micro_sim.state import RobotState
from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.recorder_node import BagRecorder
from omni_micro_tools.viewer_node import Viewer
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.camera_node import CameraNode
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.markers_node import MarkersNode
from omni_micro_vision.rendering import Sensor, render
from omni_micro_vision.tracker_node import TrackerNode
from omni_micro_vision.vision_node import VisionNode


def overrides(**values: object) -> list[Parameter]:
    return [Parameter(name.replace('__', '.'), value=value) for name, value in values.items()]


# -- dynamics_node ------------------------------------------------------------------------------
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
        node.slip_pub.publish = published.append
        node.odom_pub.publish = lambda data: None
        for _ in range(9):
            node._publish(node.grid.advance())
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
        for publisher in (node.odom_pub, node.joint_pub, node.odom_throttle_pub,
                          node.joint_throttle_pub):
            publisher.publish = sent.setdefault(publisher.topic_name, []).append
        for _ in range(12):
            node._publish(node.grid.advance())
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
        assert "matching bag_recorder's reader of /clock" in node._waiting_for()
        for topic, kind in (('/clock', Clock), ('/odom', Odometry), ('/joint_states', JointState),
                            ('/wheel_slip', JointState)):
            recorder.create_subscription(kind, topic, lambda msg: None, DATA_QOS)
        deadline = time.monotonic() + 10.0
        while node.grid.tick == 0 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert node.grid.tick > 0
    finally:
        executor.shutdown()
        recorder.destroy_node()
        node.destroy_node()


# -- vision_node --------------------------------------------------------------------------------
def assert_reads_input_only_once_matched(context, node: Node, reader_name: str,
                                            make_readers: Callable[[Node], object],
                                            input_topic: str = '/odom') -> None:
    """``node`` has no reader of ``input_topic`` (so the robot's clock would not start) until
    the readers that ``make_readers`` gives a node named ``reader_name`` are matched."""
    reader = rclpy.create_node(reader_name, context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        def reads_input() -> bool:
            return any(sub.topic_name == input_topic for sub in node.subscriptions)
        executor.add_node(node)
        executor.spin_once(timeout_sec=0.2)
        assert not reads_input()
        make_readers(reader)
        deadline = time.monotonic() + 10.0
        while not reads_input() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert reads_input()
    finally:
        executor.shutdown()
        reader.destroy_node()
        node.destroy_node()


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


# -- controller_node ----------------------------------------------------------------------------
def test_controller_node_tunes_timer1_while_it_runs_and_keeps_its_mode(context):
    node = ControllerNode(context=context)
    try:
        assert node.set_parameters([Parameter('near_period_s', value=0.2)])[0].successful
        assert node.controller.config.near_period_s == 0.2
        refused = node.set_parameters([Parameter('mode', value='model')])[0]
        assert not refused.successful and 'mode' in refused.reason
        refused = node.set_parameters([Parameter('near_period_s', value=-1.0)])[0]
        assert not refused.successful and node.controller.config.near_period_s == 0.2
    finally:
        node.destroy_node()


@pytest.mark.parametrize(('name', 'value', 'error'), [
    ('capture_uncertainty', 'guess', ParameterError),
    ('goal_m', [0.01, 0.0, 0.0], ParameterError),
    ('tolerance_m', -1e-6, ControllerConfigError),
])
def test_controller_node_refuses_bad_parameters_naming_them(context, name, value, error):
    with pytest.raises(error, match=name):
        ControllerNode(context=context, parameter_overrides=[Parameter(name, value=value)])


def test_controller_node_rejects_a_goal_in_another_frame_and_says_so(context, spy):
    node = ControllerNode(context=context)
    try:
        statuses = spy(node.status_pub)
        goal = PoseStamped()
        goal.header.frame_id = 'map'
        goal.pose.position.x = 0.01
        node._on_goal(goal)
        status = statuses.messages[-1]
        assert status.level == DiagnosticStatus.WARN and status.message == 'goal rejected'
        assert "'map'" in {value.key: value.value for value in status.values}['reason']
    finally:
        node.destroy_node()


# -- camera_node and tracker_node ---------------------------------------------------------------
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


def frame(pixels: np.ndarray, stamp_ns: int) -> tuple[Image, CameraInfo]:
    image = Image(height=pixels.shape[0], width=pixels.shape[1], encoding='mono8',
                  is_bigendian=0, step=pixels.shape[1], data=pixels.tobytes())
    image.header.stamp.sec, image.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    info = CameraInfo(height=pixels.shape[0], width=pixels.shape[1])
    info.header = image.header
    return image, info


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


def test_tracker_node_refuses_an_unknown_camera_naming_it(context):
    with pytest.raises(CameraConfigError, match="'tele'"):
        TrackerNode(context=context, parameter_overrides=overrides(cameras=['macro', 'tele']))


# -- markers_node -------------------------------------------------------------------------------
def test_markers_node_refuses_a_turned_field_that_is_not_a_number(context):
    with pytest.raises(CameraConfigError, match=r'macro\.yaw_rad'):
        MarkersNode(context=context, parameter_overrides=overrides(macro__yaw_rad=math.nan))


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


# -- bag_recorder and viewer (omni_micro_tools) -------------------------------------------------
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


@pytest.mark.parametrize(('values', 'named'), [
    ({}, 'bag must name'),
    ({'bag': 'x', 'topics': ['/nope']}, "'/nope'"),
    ({'bag': 'x', 'storage': 'zip'}, "'zip'"),
])
def test_bag_recorder_refuses_what_it_cannot_record(context, tmp_path, values, named):
    if 'bag' in values:
        values = {**values, 'bag': str(tmp_path / values['bag'])}
    with pytest.raises(ParameterError, match=named):
        BagRecorder(context=context, parameter_overrides=overrides(**values))
    assert not (tmp_path / 'x').exists()


def test_bag_recorder_never_records_over_an_existing_folder(context, tmp_path):
    (tmp_path / 'mine').mkdir()
    with pytest.raises(ParameterError, match='exists already'):
        BagRecorder(context=context, parameter_overrides=overrides(bag=str(tmp_path / 'mine')))


def test_viewer_refuses_a_port_out_of_range(context):
    with pytest.raises(ParameterError, match='70000'):
        Viewer(context=context, parameter_overrides=overrides(port=70000))


@pytest.mark.parametrize('entries, words', [
    (['markers_node'], 'each entry must be NODE:/TOPIC'),
    (['markers_node:odom'], 'each entry must be NODE:/TOPIC'),
    (['markers_node:/markers'], "markers_node reads ['/markers'], which this node does not "
                                'publish'),
])
def test_dynamics_node_refuses_awaited_readers_it_cannot_wait_for(context, entries, words):
    with pytest.raises(ParameterError, match=re.escape(words)):
        DynamicsNode(context=context, parameter_overrides=overrides(awaited_readers=entries))
