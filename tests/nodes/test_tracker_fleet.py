"""tracker_node under one camera shared by several robots, in-process: frames of coded robots in,
each robot's captures out under its namespace; a robot it cannot name gets no capture and is
reported with why and where; what it cannot track is refused in one line."""

from __future__ import annotations

import math

import numpy as np
import pytest
from adapter_helpers import frame, overrides
from rclpy.serialization import serialize_message

from omni_micro_common.conventions import CaptureUncertainty, quaternion_to_yaw
from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.rendering import InView, Sensor, render_robots
from omni_micro_vision.tracker_node import TrackerNode

FRAME_NS = 33_333_333


def test_each_robot_s_captures_come_under_its_namespace_and_a_stranger_is_reported(context, spy):
    node = TrackerNode(context=context, parameter_overrides=overrides(
        cameras=['macro'], robots=['robot_0', 'robot_3']))
    try:
        reader = node.readers[0]
        statuses = spy(reader.status_pub)
        published = {(code, kind): spy(publisher)
                     for (code, _), publishers in node.robot_publishers.items()
                     for kind, publisher in zip(('bare', 'covariance'), publishers, strict=True)}
        # robot_0 and robot_3 still; robot_5's code is printed but it is not in this run; an
        # uncoded robot (a single robot's top) cannot be named.
        robots = [InView(RobotState(0.02, 0.03, 0.5), 0), InView(RobotState(0.08, -0.02, -2.0), 3),
                  InView(RobotState(0.05, 0.05, 1.0), 5), InView(RobotState(0.0, -0.05, 0.0))]
        for index in range(4):
            pixels = render_robots(DEFAULT_RIG.macro, Sensor(), robots,
                                   np.random.default_rng([9, index]))
            image, info = frame(pixels, index * FRAME_NS)
            reader.on_info(info)
            reader.on_image(serialize_message(image))
        for code, robot in ((0, robots[0]), (3, robots[1])):
            captures = published[code, 'bare'].messages
            # Still from the third frame on: a capture each, stamped with its frame.
            assert [c.header.stamp.nanosec for c in captures] == [2 * FRAME_NS, 3 * FRAME_NS]
            for capture in captures:
                assert capture.header.frame_id == 'platform'
                position = capture.pose.position
                assert math.hypot(position.x - robot.motion.x_m,
                                  position.y - robot.motion.y_m) < 30e-6
                assert abs(quaternion_to_yaw(capture.pose.orientation.z,
                                             capture.pose.orientation.w)
                           - robot.motion.phi_rad) < 0.02
            (first, _) = published[code, 'covariance'].messages
            assert CaptureUncertainty.from_covariance(first.pose.covariance).x_sigma_m > 0
        assert {topic for topic in (publisher.topic_name for publishers in
                                     node.robot_publishers.values() for publisher in publishers)} \
            == {'/robot_0/camera/macro/pose', '/robot_0/camera/macro/pose_with_covariance',
                '/robot_3/camera/macro/pose', '/robot_3/camera/macro/pose_with_covariance'}
        status = statuses.messages[-1]
        assert status.message == ("seen: robot_0, robot_3; 2 not named: cannot tell apart: its "
                                  "code 00000 is no robot's; robot_5 is not one of this run's "
                                  "robots")
        where = {item.key: item.value for item in status.values}['not_named_at_mm']
        at = sorted(tuple(float(mm) for mm in pair.split(',')) for pair in where.split('; '))
        assert np.allclose(at, [(0.0, -50.0), (50.0, 50.0)], atol=0.03)
    finally:
        node.destroy_node()


def test_a_moving_robot_gets_no_capture_until_still_and_the_others_go_on(context, spy):
    node = TrackerNode(context=context, parameter_overrides=overrides(
        cameras=['macro'], robots=['robot_1', 'robot_2']))
    try:
        reader = node.readers[0]
        bare = {code: spy(publishers[0]) for (code, _), publishers in
                node.robot_publishers.items()}
        for index in range(5):
            # robot_1 still throughout; robot_2 moves 1 mm a frame for three frames, then stops.
            x2 = 0.08 + 1e-3 * min(index, 3)
            robots = [InView(RobotState(0.02, 0.0, 0.0), 1), InView(RobotState(x2, 0.0, 0.0), 2)]
            pixels = render_robots(DEFAULT_RIG.macro, Sensor(), robots,
                                   np.random.default_rng([4, index]))
            reader.on_image(serialize_message(frame(pixels, index * FRAME_NS)[0]))
        assert [c.header.stamp.nanosec for c in bare[1].messages] == [
            2 * FRAME_NS, 3 * FRAME_NS, 4 * FRAME_NS]
        assert bare[2].messages == []     # still only at frames 3 and 4: two of three
    finally:
        node.destroy_node()


@pytest.mark.parametrize(('values', 'named'), [
    ({'robots': ['robot_10']}, "'robot_10' is not a robot with a code of its own"),
    ({'robots': ['arm_1']}, "'arm_1' is not a robot with a code of its own"),
    ({'robots': ['robot_1', 'robot_1']}, "'robot_1' is not a robot with a code of its own"),
])
def test_robots_the_tracker_cannot_tell_are_refused_naming_them(context, values, named):
    with pytest.raises(CameraConfigError, match=named):
        TrackerNode(context=context, parameter_overrides=overrides(cameras=['macro'], **values))
