"""The camera nodes in-process (vision_node, camera_node, tracker_node): parameters checked,
inputs read only once their readers are matched, frames and captures turned into messages and
back, refusals that name the value."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import rclpy
from adapter_helpers import assert_reads_input_only_once_matched, frame, overrides
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_common.conventions import quaternion_to_yaw, yaw_to_quaternion
from omni_micro_common.qos import CAPTURE_QOS, IMAGE_QOS, camera_info_profile, latched
from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.camera_node import CameraNode
from omni_micro_vision.errors import CameraConfigError
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


def test_vision_node_says_its_first_status_and_reads_odometry_once_the_recorder_is_matched(
        context):
    """Its first status ('waiting for the robot to stop', at time 0) is latched with depth 1:
    a recorder whose reader the writer matched only after the next status (0.04 s on) never
    got it, and a fleet's bag lacked one robot's (the recorder had matched the writer, so it
    said it was recording, but not the writer the recorder). Said before the match, it could
    reach the recorder only as history, which Fast DDS does not always deliver to a reader
    matched late (eProsima/Fast-DDS#3822)."""
    def recorder_reader(recorder: Node) -> None:
        recorder.create_subscription(DiagnosticStatus, '/camera/status', lambda msg: None,
                                     latched(1000))
    assert_reads_input_only_once_matched(
        context, VisionNode(context=context, parameter_overrides=overrides(
            status_readers=['bag_recorder'])), 'bag_recorder', recorder_reader,
        first_said_on='/camera/status')


def test_a_camera_info_reader_starved_for_a_while_still_knows_of_every_frame_sent(context):
    """The tracker's and the preflight's CameraInfo reader (camera_info_profile): a driver's
    best-effort CameraInfo (SensorDataQoS, as the machine-vision drivers offer it) sent while
    the reader's process gets no CPU stays until it is read, for seconds of frames; an image
    reader's depth (10) keeps only the latest."""
    best_effort = QoSProfile(depth=IMAGE_QOS.depth, reliability=ReliabilityPolicy.BEST_EFFORT)
    driver = rclpy.create_node('camera_driver', context=context)
    reader = rclpy.create_node('preflight', context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(reader)
    try:
        deep: list[CameraInfo] = []
        shallow: list[CameraInfo] = []
        reader.create_subscription(CameraInfo, '/bench/camera_info', deep.append,
                                   camera_info_profile(best_effort))
        reader.create_subscription(CameraInfo, '/bench/camera_info', shallow.append,
                                   best_effort)
        infos = driver.create_publisher(CameraInfo, '/bench/camera_info',
                                        qos_profile_sensor_data)
        deadline = time.monotonic() + 10.0
        while infos.get_subscription_count() < 2 and time.monotonic() < deadline:
            time.sleep(0.02)
        for k in range(60):   # four seconds of a 15 Hz driver, the reader not spun meanwhile
            info = CameraInfo(width=1280, height=1024)
            info.header.stamp.nanosec = k
            infos.publish(info)
        time.sleep(0.2)
        deadline = time.monotonic() + 5.0
        while len(deep) < 60 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        executor.spin_once(timeout_sec=0.1)
        assert [info.header.stamp.nanosec for info in deep] == list(range(60))
        assert [info.header.stamp.nanosec for info in shallow] == list(range(50, 60))
    finally:
        executor.shutdown()
        driver.destroy_node()
        reader.destroy_node()


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
