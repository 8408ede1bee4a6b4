"""The per-tick messages as CDR templates: the bytes a publisher sends, the numbers back, and a
message of another layout read in full."""

import math

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from omni_micro_common.cdr import canonical_bytes
from omni_micro_common.conventions import JOINT_NAMES
from omni_micro_common.tick_messages import (
    ODOMETRY_FIELDS,
    joint_state_template,
    odometry_template,
    tick_templates,
)


def odometry(values, frame='odom'):
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = frame, 'base_link'
    (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.pose.pose.position.x,
     msg.pose.pose.position.y, msg.pose.pose.orientation.z, msg.pose.pose.orientation.w,
     msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z) = values
    return msg


VALUES = (12, 340_000_000, 0.1, -0.002, 0.38, 0.925, 0.011, -0.0003, 0.5)


def test_an_encoded_odometry_is_the_message_with_those_numbers_byte_for_byte():
    data = odometry_template().encode(VALUES)
    assert data == canonical_bytes(odometry(VALUES))
    back = deserialize_message(data, Odometry)
    assert back.pose.pose.position.y == -0.002 and back.header.stamp.nanosec == 340_000_000
    assert odometry_template().decode(data) == VALUES


def test_the_padding_is_zero_so_the_same_numbers_give_the_same_bytes_in_every_process():
    # rclpy's serialize_message leaves memory garbage in the alignment padding; a template
    # built on it would make two runs' bags differ.
    first, second = odometry_template(), odometry_template()
    assert first.encode(VALUES) == second.encode(VALUES)
    joints = JointState(name=list(JOINT_NAMES), position=[0.0] * 4, velocity=[0.0] * 4)
    joints.header.frame_id = 'base_link'
    data = canonical_bytes(joints)
    assert len(data) == 192 and data[25:28] == b'\x00\x00\x00'


def test_another_publishers_layout_is_read_in_full():
    foreign = canonical_bytes(odometry(VALUES, frame='map'))
    template = odometry_template()
    assert template.read(foreign) is None
    assert template.decode(foreign) == VALUES
    # A covariance the template does not hold is another layout too.
    msg = odometry(VALUES)
    msg.pose.covariance[0] = 1e-6
    assert template.read(canonical_bytes(msg)) is None


def test_joint_states_of_another_order_are_not_read_as_ours():
    reordered = JointState(name=list(reversed(JOINT_NAMES)), position=[1.0, 2.0, 3.0, 4.0],
                           velocity=[0.0] * 4)
    reordered.header.frame_id = 'base_link'
    assert joint_state_template().read(canonical_bytes(reordered)) is None


def test_every_tick_template_round_trips():
    templates = tick_templates('odom', 'base_link')
    rng = np.random.default_rng(1)
    for template in (templates.clock, templates.odometry, templates.joint_state, templates.slip):
        count = len(template.names)
        values = (7, 20_000_000, *rng.normal(size=count - 2))
        assert template.decode(template.encode(values)) == pytest.approx(values)


def test_the_odometry_fields_are_what_vision_node_reads():
    assert list(ODOMETRY_FIELDS)[2:4] == ['pose.pose.position.x', 'pose.pose.position.y']
    assert math.isfinite(odometry_template().decode(odometry_template().encode(VALUES))[4])


@pytest.mark.parametrize('values', [[], [('processed_ns', '20000000')],
                                    [('processed_ns', '7'), ('capture_first_ns', '123456789012'),
                                     ('capture_last_ns', '1')]])
def test_a_lockstep_report_by_hand_is_the_diagnostic_status_a_publisher_sends(values):
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    from omni_micro_common.cdr import diagnostic_status_bytes, read_diagnostic_status

    for name in ('vision_node', 'controller_node', 'x'):
        msg = DiagnosticStatus(level=DiagnosticStatus.OK, name=name, message='lockstep',
                               values=[KeyValue(key=k, value=v) for k, v in values])
        data = diagnostic_status_bytes(0, name, 'lockstep', '', values)
        assert data == canonical_bytes(msg)
        assert read_diagnostic_status(data) == (0, name, 'lockstep', '', values)


def test_a_report_round_trips_and_a_broken_one_is_named():
    from omni_micro_common.cdr import diagnostic_status_bytes
    from omni_micro_common.errors import LockstepError
    from omni_micro_common.lockstep import ACK_MESSAGE, Ack
    from omni_micro_common.lockstep_reporting import decode_ack_bytes

    ack = Ack('vision_node', 40_000_000, captures_ns=(20_000_000, 40_000_000))
    data = diagnostic_status_bytes(0, 'vision_node', ACK_MESSAGE, '', ack.to_values())
    assert decode_ack_bytes(data) == ack
    assert decode_ack_bytes(diagnostic_status_bytes(0, 'x', 'ready', '', [])) is None
    with pytest.raises(LockstepError, match='does not parse'):
        decode_ack_bytes(data[:13])


def test_a_nodes_last_lockstep_report_is_said_again_only_while_no_other_comes(context,
                                                                            monkeypatch):
    """A report lost to a reader not yet matched would leave the robot's time standing: the
    last is sent again after REPORT_REPEAT_S of wall time without another (on the node's own
    steady timer), and not while reports keep coming."""
    import time
    from types import SimpleNamespace

    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node

    from omni_micro_common import lockstep_reporting
    from omni_micro_common.lockstep import Ack
    from omni_micro_common.lockstep_reporting import REPORT_REPEAT_S, LockstepReporter

    node = Node('controller_node', namespace='robot_1', context=context)
    reporter = LockstepReporter(node)
    assert reporter.name == 'robot_1/controller_node'
    sent: list[bytes] = []
    monkeypatch.setattr(reporter._publisher, 'publish', sent.append)   # what goes out, in order
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    try:
        # The timer says it again, unprompted, once nothing else came.
        reporter.report(Ack(reporter.name, 20_000_000))
        deadline = time.monotonic() + 10.0
        while len(sent) < 2 and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert sent[:2] == [sent[0]] * 2
        # When, on a clock of the test's: only after REPORT_REPEAT_S without another report.
        now = [100.0]
        monkeypatch.setattr(lockstep_reporting, 'time', SimpleNamespace(monotonic=lambda: now[0]))
        sent.clear()
        for at_s, report_ns in ((0.0, 40_000_000), (0.05, None), (0.09, 60_000_000),
                                (0.15, None), (0.2, None), (0.27, None)):
            now[0] = 100.0 + at_s
            if report_ns is None:
                reporter._repeat()
            else:
                reporter.report(Ack(reporter.name, report_ns))
        said = [lockstep_reporting.decode_ack_bytes(data) for data in sent]
        assert [ack.processed_ns if ack else None for ack in said] == [
            40_000_000, 60_000_000, 60_000_000]   # the last, said again at 0.2 s only
        assert REPORT_REPEAT_S == 0.1
    finally:
        executor.shutdown()
        node.destroy_node()
