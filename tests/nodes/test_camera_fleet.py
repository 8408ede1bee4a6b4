"""camera_node over a fleet's robots, in-process: every frame draws every robot with its
code, once every robot's odometry has reached the frame's time, and tracker_node with the same
robots names each one and publishes its captures under its namespace (the camera's codes are the
tracker's); what it cannot draw is refused in one line."""

from __future__ import annotations

import math

import pytest
from adapter_helpers import overrides
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_common.cdr import read_diagnostic_status
from omni_micro_common.conventions import quaternion_to_yaw, yaw_to_quaternion
from omni_micro_common.lockstep_reporting import decode_ack_bytes
from omni_micro_vision.camera_node import CameraNode
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.tracker_node import TrackerNode

ROBOTS = ['robot_0', 'robot_2']
POSES = {'robot_0': (0.02, 0.03, 0.5), 'robot_2': (0.08, -0.02, -2.0)}
TICKS_NS = [tick * 20_000_000 for tick in range(6)]   # 0 .. 0.1 s on the 50 Hz grid


def odometry(pose: tuple[float, float, float], nanosec: int) -> bytes:
    message = Odometry()
    message.header.stamp.nanosec = nanosec
    message.pose.pose.position.x, message.pose.pose.position.y = pose[:2]
    message.pose.pose.orientation.z, message.pose.pose.orientation.w = yaw_to_quaternion(pose[2])
    return serialize_message(message)


def test_each_robot_drawn_with_its_code_is_named_by_the_tracker_under_its_namespace(context,
                                                                                   spy):
    camera = CameraNode(context=context, parameter_overrides=overrides(cameras=['macro'],
                                                                       robots=ROBOTS))
    tracker = TrackerNode(context=context, parameter_overrides=overrides(cameras=['macro'],
                                                                         robots=ROBOTS))
    try:
        images, infos = spy(camera.streams[0].image_pub), spy(camera.streams[0].info_pub)
        assert [topic for topic, _ in camera.sources] == ['/robot_0/odom', '/robot_2/odom']
        # robot_0's odometry first, up to 0.1 s: no frame while robot_2 has sent none.
        for nanosec in TICKS_NS:
            camera._on_odometry(odometry(POSES['robot_0'], nanosec), robot=0)
        assert images.messages == []
        for nanosec in TICKS_NS:
            camera._on_odometry(odometry(POSES['robot_2'], nanosec), robot=1)
        frames = [deserialize_message(data, Image) for data in images.messages]
        assert [f.header.stamp.nanosec for f in frames] == [0, 33_333_333, 66_666_667,
                                                             100_000_000]
        reader = tracker.readers[0]
        published = {code: spy(publishers[0])
                     for (code, _), publishers in tracker.robot_publishers.items()}
        # Each robot's lockstep gate hears of its own captures only.
        reports = {code: spy(lockstep._publisher)
                   for code, lockstep in tracker.robot_lockstep.items()}
        for info, image in zip(infos.messages, images.messages, strict=True):
            reader.on_info(deserialize_message(info, CameraInfo))
            reader.on_image(image)
        for code, name in ((0, 'robot_0'), (2, 'robot_2')):
            captures = published[code].messages
            # Named in every frame, still from the third on: a capture each, where it stands.
            assert [c.header.stamp.nanosec for c in captures] == [66_666_667, 100_000_000]
            x, y, phi = POSES[name]
            for capture in captures:
                position = capture.pose.position
                assert math.hypot(position.x - x, position.y - y) < 30e-6
                assert abs(quaternion_to_yaw(capture.pose.orientation.z,
                                             capture.pose.orientation.w) - phi) < 0.02
            acks = [decode_ack_bytes(data) for data in reports[code].messages]
            assert {read_diagnostic_status(data)[1] for data in reports[code].messages} == {
                f'{name}/tracker_node'}
            assert [ack.captures_ns for ack in acks if ack and ack.captures_ns] == [
                (66_666_667, 66_666_667), (100_000_000, 100_000_000)]
            assert acks[-1] is not None and acks[-1].frame_handled_ns == 100_000_000
    finally:
        tracker.destroy_node()
        camera.destroy_node()


@pytest.mark.parametrize('values, named', [
    ({'robots': ['robot 1']}, "'robot 1' is not a robot with a code of its own"),
    ({'robots': ['robot_0'], 'scene': 'chessboard'}, 'robots: only with scene robot'),
])
def test_robots_it_cannot_draw_are_refused_naming_them(context, values, named):
    with pytest.raises(CameraConfigError, match=named):
        CameraNode(context=context, parameter_overrides=overrides(**values))
