"""A bag's messages published again on their topics with their original spacing, as ``ros2 bag
play`` would (rosbag2's player is not available here): the node of ``omni-micro replay``.

Each topic is published with the QoS its graph publisher offers (:mod:`omni_micro_tools.topics`), a
latched one deep enough that no message is replaced before a reader has it. With ``sync`` nodes it
keeps pace with them: no more than REPLAY_SYNC_WINDOW stamped messages beyond what the slowest has
reported on /lockstep as handled, so a node that cannot keep up loses nothing.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from omni_micro_common.conventions import stamp_ns
from omni_micro_common.errors import LockstepError
from omni_micro_common.installed import use_dds_profile
from omni_micro_common.lockstep import ACK_TOPIC, REPLAY_SYNC_WINDOW
from omni_micro_common.lockstep_reporting import LOCKSTEP_QOS, decode_ack
from omni_micro_common.messages import message_class
from omni_micro_tools.bag_reading import BagMessages
from omni_micro_tools.errors import ReplayError
from omni_micro_tools.topics import RECORDABLE_TOPICS, TopicSpec

# The depth of a topic the graph does not know (a user's own in the bag).
UNKNOWN_TOPIC_DEPTH = 1000
# How long a sync node may stay silent before the replay stops.
SYNC_TIMEOUT_S = 30.0


def header_stamp_ns(msg: object) -> int | None:
    header = getattr(msg, 'header', None)
    return None if header is None else stamp_ns(header.stamp)

# How often play() says how far it is, in wall time.
PROGRESS_EVERY_S = 1.0


class BagPlayer:
    """``data`` must be decoded when ``sync`` names nodes (the stamps are read from the
    messages); otherwise its raw bytes are published as they are."""

    def __init__(self, data: BagMessages, topics: Sequence[str], sync: Sequence[str] = (),
                 domain_id: int | None = None) -> None:
        self.data = data
        self.topics = list(topics)
        self.sync = list(sync)
        self.events = sorted((stamp, topic, index) for topic in self.topics
                             for index, stamp in enumerate(data.timestamps[topic]))
        use_dds_profile()   # as the graph's nodes it replays to have it
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node('bag_replay', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.publishers = {}
        for topic in self.topics:
            spec = RECORDABLE_TOPICS.get(topic, TopicSpec(data.msgtypes[topic],
                                                          UNKNOWN_TOPIC_DEPTH))
            # A latched status of depth 1 sent twice in quick succession at --rate 20 lost the
            # first: deep enough for none to be replaced; the others keep their depth (camera
            # frames are paced by it).
            depth = max(spec.depth, UNKNOWN_TOPIC_DEPTH) if spec.latched else spec.depth
            self.publishers[topic] = self.node.create_publisher(
                message_class(data.msgtypes[topic]), topic, spec.reader_profile(depth))
        self.handled: dict[str, int] = {}
        self.sent_stamps: list[int] = []
        self.published = 0
        if self.sync:
            self.node.create_subscription(DiagnosticStatus, ACK_TOPIC, self._on_report,
                                          LOCKSTEP_QOS)

    def _on_report(self, msg: DiagnosticStatus) -> None:
        try:
            ack = decode_ack(msg)
        except LockstepError:
            return
        if ack is not None and ack.node in self.sync:
            # A tracker reads no odometry: what it handled is the frames.
            done = ack.processed_ns if ack.processed_ns is not None else ack.frame_handled_ns
            if done is not None:
                self.handled[ack.node] = max(self.handled.get(ack.node, -1), done)

    def wait_for_subscribers(self, timeout_s: float) -> None:
        """Until every replayed topic has a subscriber.

        Raises
        ------
        ReplayError
            Naming the topics nobody subscribes after ``timeout_s``.
        """
        deadline = time.monotonic() + timeout_s
        while any(p.get_subscription_count() == 0 for p in self.publishers.values()):
            if time.monotonic() > deadline:
                lonely = [t for t, p in self.publishers.items() if p.get_subscription_count() == 0]
                raise ReplayError(f'no subscriber on {lonely} after {timeout_s} s')
            time.sleep(0.05)
        time.sleep(0.5)   # discovery shows a reader a little before it is matched

    def _wait_for_sync(self, behind: int) -> None:
        """Until every sync node handled the message sent ``behind`` stamped ones ago."""
        if not self.sync or len(self.sent_stamps) < behind:
            return
        needed = self.sent_stamps[-behind]
        deadline = time.monotonic() + SYNC_TIMEOUT_S
        while any(self.handled.get(name, -1) < needed for name in self.sync):
            if time.monotonic() > deadline:
                silent = sorted(set(self.sync) - set(self.handled)) or self.sync
                raise ReplayError(f'--sync: {silent} reported nothing on /lockstep for '
                                  f'{SYNC_TIMEOUT_S:g} s (is it running, in this domain?)')
            self.executor.spin_once(timeout_sec=0.05)

    @property
    def duration_s(self) -> float:
        """The bag's span, first message to last, in its own time."""
        return (self.events[-1][0] - self.events[0][0]) * 1e-9

    def play(self, rate: float, loop: bool = False,
             on_progress: Callable[[int, float], None] | None = None) -> int:
        """Publish every message at its original spacing divided by ``rate`` (again and again
        with ``loop``, until interrupted); return how many were published. ``on_progress`` is
        called about every PROGRESS_EVERY_S of wall time with the messages published in this
        pass and how far into the bag it is (s).

        Raises
        ------
        ReplayError
            A sync node fell silent.
        """
        while True:
            first = self.events[0][0]
            started = reported = time.monotonic()
            for done, (stamp, topic, index) in enumerate(self.events, start=1):
                delay = (stamp - first) * 1e-9 / rate - (time.monotonic() - started)
                if delay > 0:
                    time.sleep(delay)
                self._wait_for_sync(REPLAY_SYNC_WINDOW)
                self.publishers[topic].publish(self.data.raw[topic][index])
                self.published += 1
                if on_progress is not None and time.monotonic() - reported >= PROGRESS_EVERY_S:
                    reported = time.monotonic()
                    on_progress(done, (stamp - first) * 1e-9)
                if self.sync:
                    header_ns = header_stamp_ns(self.data.messages[topic][index])
                    if header_ns is not None:
                        self.sent_stamps.append(header_ns)
            if not loop:
                break
        self._wait_for_sync(1)
        time.sleep(0.5)   # let reliable writers hand over the tail before the node goes
        return self.published

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)
