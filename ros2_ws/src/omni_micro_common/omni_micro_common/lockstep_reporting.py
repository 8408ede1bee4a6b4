"""The lockstep reports on /lockstep as nodes publish and the robot reads them (the protocol
itself is :mod:`omni_micro_common.lockstep`, plain Python)."""

from __future__ import annotations

import struct
import time

from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.clock import Clock, ClockType
from rclpy.node import Node

from omni_micro_common.cdr import diagnostic_status_bytes, read_diagnostic_status
from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import ACK_MESSAGE, ACK_TOPIC, Ack
from omni_micro_common.lockstep_groups import qualified_node_name
from omni_micro_common.qos import LOCKSTEP_QOS, PER_TICK_PUBLISHER_EVENTS

# How long (wall time) a node's last report stands before it is said again. A report sent before
# the robot's reader of /lockstep matched this writer is lost, and a node reports only as its
# inputs come, which the robot, waiting for that report, then never sends: a fleet's run once
# stood at 0.04 s for five minutes so. Said again, a report tells the gate nothing it did not
# know, so the run is the same whenever the repeat comes.
REPORT_REPEAT_S = 0.1


class LockstepReporter:
    """Publishes this node's lockstep reports (see :mod:`omni_micro_common.lockstep`).

    Not counted among the node's publications: they are the graph's plumbing, not its data.
    A node in a robot's namespace reports as ``robot_k/name`` (several robots, one lockstep);
    ``name`` reports under another (a fleet's coordinator, once for each robot). The last
    report is said again after REPORT_REPEAT_S of wall time without another.
    """

    def __init__(self, node: Node, name: str | None = None) -> None:
        self.name = name or qualified_node_name(node.get_namespace(), node.get_name())
        self._publisher = node.create_publisher(DiagnosticStatus, ACK_TOPIC, LOCKSTEP_QOS,
                                               event_callbacks=PER_TICK_PUBLISHER_EVENTS)
        self._last: bytes | None = None
        self._sent_at = 0.0
        # On the steady clock: the robot's time stands while the report is missing.
        node.create_timer(REPORT_REPEAT_S, self._repeat,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

    def report(self, ack: Ack) -> None:
        # Serialized by hand (omni_micro_common.cdr): one report per tick per node.
        self._last = diagnostic_status_bytes(0, self.name, ACK_MESSAGE, '', ack.to_values())
        self._send(self._last)

    def _send(self, data: bytes) -> None:
        self._publisher.publish(data)
        self._sent_at = time.monotonic()

    def _repeat(self) -> None:
        if self._last is not None and time.monotonic() - self._sent_at >= REPORT_REPEAT_S:
            self._send(self._last)


def decode_ack_bytes(data: bytes) -> Ack | None:
    """:func:`decode_ack` of a raw /lockstep message.

    Raises
    ------
    LockstepError
        A report that does not parse, or with a missing, unknown or malformed field.
    """
    try:
        _, name, message, _, values = read_diagnostic_status(data)
    except (ValueError, IndexError, struct.error) as error:
        raise LockstepError(f'a /lockstep message that does not parse: {error}') from None
    if message != ACK_MESSAGE:
        return None
    return Ack.from_values(name, values)


def decode_ack(msg: DiagnosticStatus) -> Ack | None:
    """The lockstep report a /lockstep message carries (None for another kind of status).

    Raises
    ------
    LockstepError
        A report with a missing, unknown or malformed field, named.
    """
    if msg.message != ACK_MESSAGE:
        return None
    return Ack.from_values(msg.name, ((kv.key, kv.value) for kv in msg.values))
