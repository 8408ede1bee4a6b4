"""controller_node in-process: parameters checked at start and at run time, goals in another
frame rejected, each mode's captures (still, in motion, before the goal or the first wheel
state) handled as the twin hands them over."""

from __future__ import annotations

import math

import pytest
from adapter_helpers import assert_reads_input_only_once_matched, overrides
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from geometry_msgs.msg import PoseStamped
from rclpy.parameter import Parameter
from rclpy.serialization import serialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from omni_micro_common.conventions import (
    JOINT_NAMES,
    STATUS_TIME_KEY,
    CaptureUncertainty,
    stamp_ns,
)
from omni_micro_common.errors import ParameterError
from omni_micro_common.lockstep import Ack
from omni_micro_common.qos import DATA_QOS, STATUS_QOS
from omni_micro_common.topic_names import CAPTURE_IN_MOTION_TOPICS
from omni_micro_control.controller_node import ControllerNode
from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import VisionFeedbackController
from omni_micro_control.servo_session import ServoSession
from omni_micro_vision.capture_messages import capture_pose, with_uncertainty


def test_controller_node_reads_wheels_and_goals_only_once_its_moves_reach_their_readers(
        context):
    """A first move sent before a reader was matched is lost to it (reliable, volatile): in a
    suite run markers_node never got one, and the lockstep waited for it for good. The robot's
    clock waits for the controller's /joint_states reader, the goal for its /goal_pose one."""
    assert_reads_input_only_once_matched(
        context, ControllerNode(context=context, parameter_overrides=overrides(
            trajectory_readers=['markers_node'])), 'markers_node',
        lambda markers: markers.create_subscription(JointTrajectory, '/wheel_trajectory',
                                                    lambda msg: None, DATA_QOS),
        input_topic='/joint_states')


def test_controller_node_says_it_is_idle_and_listens_once_the_recorder_is_matched(context):
    """Said before its status writer matched the recorder, the first status ('idle', latched)
    could reach the recorder only as history, which Fast DDS does not always deliver to a
    reader matched late (eProsima/Fast-DDS#3822): a fleet's bag, composed at twice real time
    beside busy processes, lacked one controller's 'idle'."""
    assert_reads_input_only_once_matched(
        context, ControllerNode(context=context, parameter_overrides=overrides(
            status_readers=['bag_recorder'])), 'bag_recorder',
        lambda recorder: recorder.create_subscription(DiagnosticStatus, '/controller/status',
                                                      lambda msg: None, STATUS_QOS),
        input_topic='/joint_states', first_said_on='/controller/status')


def test_controller_node_tunes_timer1_while_it_runs_and_keeps_its_mode(context):
    node = ControllerNode(context=context)
    assert isinstance(node.controller, VisionFeedbackController)
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


def test_controller_node_in_the_servo_mode_corrects_from_captures_in_motion(context, spy,
                                                                            monkeypatch):
    """It reads /camera/<name>/pose_in_motion, starts a plan made while rolling on the grid after
    the capture's age and its lead, and says on /lockstep which of both kinds it has handled."""
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('mode', value='servo'), Parameter('goal_m', value=[0.001, 0.0]),
        Parameter('captures_per_stop', value=1)])
    try:
        assert set(CAPTURE_IN_MOTION_TOPICS.values()) <= {s.topic_name for s in node.subscriptions}
        acks: list[Ack] = []
        monkeypatch.setattr(node.lockstep, 'report', acks.append)
        trajectories = spy(node.trajectory_pub)
        still = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                           velocity=[0.0] * len(JOINT_NAMES))
        still.header.stamp.sec, still.header.stamp.nanosec = 0, 200_000_000
        node._on_joint_state(serialize_message(still))
        uncertainty = CaptureUncertainty(0.1e-6, 0.1e-6, 1e-4)
        node.captures.on_capture_with_covariance(
            with_uncertainty(capture_pose(0, 200_000_000, 'platform', 0.0, 0.0, 0.0),
                             uncertainty), camera='micro')
        assert [stamp_ns(t.header.stamp) for t in trajectories.messages] == [220_000_000]
        node.captures.on_capture_with_covariance(
            with_uncertainty(capture_pose(0, 300_000_000, 'platform', 5e-5, 0.0, 0.0),
                             uncertainty), camera='micro', in_motion=True)
        # 0.3 s + 0.05 s (the age it counts on alone) + 0.02 s, on the 20 ms grid.
        assert stamp_ns(trajectories.messages[-1].header.stamp) == 380_000_000
        assert (acks[-1].capture_handled_ns, acks[-1].motion_handled_ns) == (200_000_000,
                                                                             300_000_000)
        # A broken capture in motion is as good as none, and still said handled.
        node.captures.on_capture_with_covariance(
            with_uncertainty(capture_pose(0, 400_000_000, 'platform', math.nan, 0.0, 0.0),
                             uncertainty), camera='micro', in_motion=True)
        assert len(trajectories.messages) == 2 and acks[-1].motion_handled_ns == 400_000_000
        # A goal's tolerance may change while it runs (a fleet's coordinator sets each goal's),
        # checked; the servo's own settings may not.
        assert node.set_parameters([Parameter('tolerance_m', value=1e-6)])[0].successful
        assert node.controller.config.tolerance_m == 1e-6
        refused = node.set_parameters([Parameter('tolerance_m', value=-1.0)])[0]
        assert not refused.successful and 'tolerance_m must be a number > 0' in refused.reason
        refused = node.set_parameters([Parameter('servo.crawl_m', value=1e-4)])[0]
        assert not refused.successful
        assert refused.reason.startswith("['servo.crawl_m'] are fixed while the servo runs")
        assert node.controller.config.tolerance_m == 1e-6
        # A driver's captures in motion measured 90 ms old by the tracker: the servo takes that
        # as its bound, says so naming the driver's topic, and starts its corrections that late
        # after a capture's stamp; an age under its own bound, or no age, changes nothing.
        warnings: list[str] = []
        monkeypatch.setattr(node.get_logger(), 'warning', warnings.append)
        for said in ('garbage', '0.03', '0.09'):
            node._on_tracker_status(DiagnosticStatus(values=[
                KeyValue(key='capture_age_s', value=said),
                KeyValue(key='image_topic', value='/bench/camera/image_raw')]), camera='micro')
        assert warnings == [
            "micro: frames from /bench/camera/image_raw give captures in motion up to 90.0 ms "
            "old (tracker_status), later than the servo's bound of 50.0 ms (servo.capture_age_s): "
            "it starts its corrections 90.0 ms after a capture's stamp"]
        assert isinstance(node.controller, ServoSession)
        assert node.controller.config.capture_age_s == pytest.approx(0.09)
        node.captures.on_capture_with_covariance(
            with_uncertainty(capture_pose(0, 500_000_000, 'platform', 8e-5, 0.0, 0.0),
                             uncertainty), camera='micro', in_motion=True)
        # 0.5 s + 0.09 s + 0.02 s, on the 20 ms grid.
        assert stamp_ns(trajectories.messages[-1].header.stamp) == 620_000_000
    finally:
        node.destroy_node()


@pytest.mark.parametrize(('namespace', 'frame'), [('', 'base_link'),
                                                 ('robot_1', 'robot_1/base_link')])
def test_a_robots_moves_and_stops_are_in_its_own_base_frame(context, spy, namespace, frame):
    """The single robot's commands in base_link, a fleet robot's in its own (REP-105 per robot,
    as its odometry and joint states): two robots' commands never name one frame."""
    node = ControllerNode(context=context, namespace=namespace, parameter_overrides=[
        Parameter('mode', value='servo'), Parameter('goal_m', value=[0.001, 0.0]),
        Parameter('captures_per_stop', value=1)])
    try:
        trajectories = spy(node.trajectory_pub)
        still = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                           velocity=[0.0] * len(JOINT_NAMES))
        still.header.stamp.sec, still.header.stamp.nanosec = 0, 200_000_000
        node._on_joint_state(serialize_message(still))
        node.captures.on_capture_with_covariance(with_uncertainty(
            capture_pose(0, 200_000_000, 'platform', 0.0, 0.0, 0.0),
            CaptureUncertainty(0.1e-6, 0.1e-6, 1e-4)), camera='micro')
        node.stop_robot()
        (move, stop) = trajectories.messages
        assert move.points and not stop.points
        assert [move.header.frame_id, stop.header.frame_id] == [frame, frame]
    finally:
        node.destroy_node()


@pytest.mark.parametrize('wheels_first', [True, False])
def test_a_capture_before_the_first_wheel_state_counts_as_one_after_it(context, monkeypatch,
                                                                        wheels_first):
    """A capture and the wheel states come on different topics, in either order: a capture
    that comes before the robot's first wheel state is held and handled once it comes, so the
    servo counts it either way (it once skipped it: one capture in motion fewer in the status,
    and another bag, in one run of a dozen beside busy processes)."""
    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('mode', value='servo'), Parameter('goal_m', value=[0.001, 0.0])])
    try:
        acks: list[Ack] = []
        monkeypatch.setattr(node.lockstep, 'report', acks.append)
        first = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                           velocity=[0.0] * len(JOINT_NAMES))
        uncertainty = CaptureUncertainty(0.1e-6, 0.1e-6, 1e-4)

        def captures() -> None:
            node.captures.on_capture_with_covariance(
                with_uncertainty(capture_pose(0, 35_333_333, 'platform', 0.0, 0.0, 0.0),
                                 uncertainty), camera='macro', in_motion=True)
            node.captures.on_capture_with_covariance(
                with_uncertainty(capture_pose(0, 33_333_333, 'platform', 0.0, 0.0, 0.0),
                                 uncertainty), camera='macro')

        if wheels_first:
            node._on_joint_state(serialize_message(first))
            captures()
        else:
            captures()
            assert isinstance(node.controller, ServoSession)
            assert node.controller.captures_in_motion == 0
            assert all(ack.motion_handled_ns == -1 for ack in acks)
            node._on_joint_state(serialize_message(first))
        assert isinstance(node.controller, ServoSession)
        assert node.controller.captures_in_motion == 1
        assert (acks[-1].capture_handled_ns, acks[-1].motion_handled_ns) == (33_333_333,
                                                                             35_333_333)
    finally:
        node.destroy_node()


@pytest.mark.parametrize(('name', 'value'), [('servo.crawl_m', -1.0), ('servo.max_moves', 0),
                                             ('servo.filter.travel_noise', 0.0),
                                             ('open_loop_duration_s', 1.0)])
def test_controller_node_refuses_bad_servo_parameters_naming_them(context, name, value):
    with pytest.raises(ControllerConfigError, match=name.rsplit('.', 1)[-1]):
        ControllerNode(context=context, parameter_overrides=[
            Parameter('mode', value='servo'), Parameter(name, value=value)])


@pytest.mark.parametrize('goal_time, counts_from_s', [('arrival', 7.0), ('stamp', 5.0)])
def test_controller_node_counts_a_goal_from_its_arrival_or_its_stamp(context, spy, goal_time,
                                                                      counts_from_s):
    """A fleet's coordinator stamps each goal with the end it follows (goal_time: stamp): timer2
    counts from there, however late the goal came; the end of a goal is reported on /lockstep
    for the coordinator to hold time by."""
    from omni_micro_common.lockstep_reporting import decode_ack_bytes
    from omni_micro_control.feedback import Finished, Outcome

    node = ControllerNode(context=context, parameter_overrides=overrides(goal_time=goal_time))
    try:
        spy(node.status_pub)
        reports = spy(node.lockstep._publisher)
        node.robot_time_s = 7.0   # the robot's time when the goal arrives
        goal = PoseStamped()
        goal.header.frame_id = 'platform'
        goal.header.stamp.sec = 5
        goal.pose.position.x = 0.01
        node._on_goal(goal)
        assert isinstance(node.controller, VisionFeedbackController)
        settle = node.controller.config.settle_wait_s
        assert node.controller.deadline_s == pytest.approx(counts_from_s + settle)
        node.report(Finished(Outcome.REACHED, 'there', 1, None), at_s=7.25)
        node.report_lockstep()
        ack = decode_ack_bytes(reports.messages[-1])
        assert ack is not None and ack.outcome_ns == 7_250_000_000
    finally:
        node.destroy_node()


def test_controller_node_refuses_an_unknown_goal_time(context):
    with pytest.raises(ParameterError, match=r"goal_time must be one of \['arrival', 'stamp'\]"):
        ControllerNode(context=context, parameter_overrides=overrides(goal_time='soon'))


@pytest.mark.parametrize('mode', ['servo', 'paper'])
def test_a_capture_that_came_before_its_goal_counts_as_if_it_came_after(context, spy, mode,
                                                                        monkeypatch):
    """A fleet's coordinator hands a robot its goal stamped with another robot's end, and time
    runs on up to the lockstep's lead meanwhile: a capture stamped after that end can reach the
    controller before the goal. It counts as the twin counts it, after the goal; one stamped
    before the goal is the robot idle, as before. (The servo counts from the goal's stamp, the
    paper's rule from timer2 past it.)"""
    node = ControllerNode(context=context, parameter_overrides=[
        *overrides(goal_time='stamp'), Parameter('mode', value=mode),
        Parameter('captures_per_stop', value=2)])
    try:
        statuses = spy(node.status_pub)   # from 'idle' on
        node.publish_status(DiagnosticStatus.OK, 'idle', at_s=0.0)
        trajectories = spy(node.trajectory_pub)
        acks: list[Ack] = []
        monkeypatch.setattr(node.lockstep, 'report', acks.append)
        still = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                           velocity=[0.0] * len(JOINT_NAMES))
        still.header.stamp.sec = 5
        node._on_joint_state(serialize_message(still))
        uncertainty = CaptureUncertainty(0.1e-6, 0.1e-6, 1e-4)
        for sec, nanosec in ((4, 980_000_000), (5, 0), (5, 20_000_000)):
            node.captures.on_capture_with_covariance(with_uncertainty(
                capture_pose(sec, nanosec, 'platform', 0.0, 0.0, 0.0), uncertainty),
                camera='micro')
        assert trajectories.messages == []
        goal = PoseStamped()
        goal.header.frame_id = 'platform'
        goal.header.stamp.sec = 5
        goal.pose.position.x = 0.001
        node._on_goal(goal)
        messages = [status.message for status in statuses.messages]
        if mode == 'servo':
            # The two captures at 5.00 s and 5.02 s: a move from rest, which says the goal taken,
            # its command already on /lockstep (a fleet's coordinator releases time on it).
            assert messages == ['idle', 'moving']
            (trajectory,) = trajectories.messages
            moving = {v.key: v.value for v in statuses.messages[-1].values}
            assert float(moving[STATUS_TIME_KEY]) == pytest.approx(5.02)
            assert acks[-1].command_ns == stamp_ns(trajectory.header.stamp)
        else:
            assert messages == ['idle', 'settling'] and trajectories.messages == []
    finally:
        node.destroy_node()


def test_a_paper_controller_waits_for_captures_as_late_as_the_tracker_says_they_come(
        context, monkeypatch):
    """A driver's captures measured 1.7 s old by the tracker (a starved host, a slow link): the
    paper's controller says so once, naming the driver's topic, and its capture timeouts count
    from timer2's end plus that; no age, or a younger one, changes nothing."""
    from omni_micro_control.feedback import Phase

    node = ControllerNode(context=context)
    try:
        warnings: list[str] = []
        monkeypatch.setattr(node.get_logger(), 'warning', warnings.append)
        for said in ('garbage', '1.7', '0.4'):
            node._on_tracker_status(DiagnosticStatus(values=[
                KeyValue(key='capture_age_s', value=said),
                KeyValue(key='image_topic', value='/bench/camera/image_raw')]), camera='macro')
        assert warnings == [
            'macro: frames from /bench/camera/image_raw give captures up to 1700.0 ms old '
            '(tracker_status): the capture timeouts (3 x 1 s) count from 1700.0 ms after timer2']
        goal = PoseStamped()
        goal.header.frame_id = 'platform'
        goal.pose.position.x = 0.01
        node._on_goal(goal)   # at the robot's time 0: timer2 ends at 0.1 s
        assert isinstance(node.controller, VisionFeedbackController)
        node.robot_time_s = 0.1 + 1.7 + 0.9
        node._on_timer()
        assert len(warnings) == 1 and node.controller.phase is Phase.SETTLING
        node.robot_time_s = 0.1 + 1.7 + 1.1
        node._on_timer()
        assert warnings[1:] == [
            'no capture 1 x 1 s and the 1.700 s the cameras say their captures take after '
            'timer2; waiting again (try 2 of 3)']
    finally:
        node.destroy_node()
