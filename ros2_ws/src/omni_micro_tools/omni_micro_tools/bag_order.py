"""The order a finished bag holds its messages in, so that the same run gives the same file.

A recorder receives messages in the order the machine delivers them, and its clock at arrival
depends on the machine's load. A finished bag instead holds each message

- at the simulated time it belongs to (its *event time*): a stamped message's header stamp, a
  /clock message's clock, a MarkerArray's first marker's stamp, a status's ``status_time_s``
  (omni_micro_common.conventions.STATUS_TIME_KEY); a message without one, or with a time from 0
  in a bag recorded on the wall clock (a real robot's run), keeps its arrival time;
  never earlier than the message before it on its topic (a topic keeps its publication order);
- in one order: by event time, then by topic (``TOPIC_ORDER``; a fleet robot's topics
  where the single robot's are, robot by robot), then by publication order;
- serialized canonically (rosbags' CDR, padding zeroed: a publisher may leave garbage in it);
- up to an end the run defines: its last outcome plus ``BAG_TAIL_S`` of simulated time, or, for
  a bag whose recorder died, ``RECOVERY_WINDOW_S`` before the latest message (what came later may
  be incomplete).

Plain Python (no rclpy): ``omni-micro bag-recover`` uses it too.
"""

from __future__ import annotations

import math
import struct
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

from omni_micro_common.clocks import is_wall_clock
from omni_micro_common.conventions import OUTCOME_KEY, STATUS_TIME_KEY
from omni_micro_common.topic_names import CLOCK_TOPIC, CONTROLLER_STATUS_TOPIC, MARKERS_TOPIC
from omni_micro_tools.topics import (
    BAG_TAIL_S,
    IMAGE_TYPES,
    RECORDABLE_TOPICS,
    TOPIC_ORDER,
    robot_and_topic,
)

# A killed recorder's last messages of a tick may still have been on their way: a recovered
# bag ends this far (simulated time) before its latest message.
RECOVERY_WINDOW_S = 1.0

# The catalogue's types of the messages ordered by a stamp of their own.
STATUS_TYPE = RECORDABLE_TOPICS[CONTROLLER_STATUS_TOPIC].msgtype
CLOCK_TYPE = RECORDABLE_TOPICS[CLOCK_TOPIC].msgtype
MARKERS_TYPE = RECORDABLE_TOPICS[MARKERS_TOPIC].msgtype
# Types whose serialization starts with a std_msgs/Header (its stamp first).
HEADER_FIRST = frozenset({
    'nav_msgs/msg/Odometry', 'sensor_msgs/msg/JointState', 'sensor_msgs/msg/Image',
    'sensor_msgs/msg/CameraInfo', 'trajectory_msgs/msg/JointTrajectory',
    'geometry_msgs/msg/PoseStamped', 'geometry_msgs/msg/PoseWithCovarianceStamped'})

# One stored message: topic, type, log time (ns), serialized data.
Stored = tuple[str, str, int, bytes]


def _stamp_at(data: bytes, offset: int) -> int:
    order = '<' if data[1] & 1 else '>'
    sec, nanosec = struct.unpack_from(f'{order}iI', data, offset)
    return sec * 1_000_000_000 + nanosec


def marker_array_stamp_ns(data: bytes) -> int | None:
    """The time of a serialized MarkerArray: its first marker's stamp (after the array's
    length), None for an empty array."""
    (count,) = struct.unpack_from('<I' if data[1] & 1 else '>I', data, 4)
    return _stamp_at(data, 8) if count else None


def event_time_ns(msgtype: str, data: bytes, decoded: Any) -> int | None:
    """The simulated time a message belongs to (see the module docstring), None if it says none.
    ``decoded`` is the message as rosbags decodes it (used where bytes do not say it plainly)."""
    if msgtype in HEADER_FIRST or msgtype == CLOCK_TYPE:
        return _stamp_at(data, 4)    # after the 4-byte CDR encapsulation
    if msgtype == MARKERS_TYPE:
        return marker_array_stamp_ns(data)
    if msgtype == STATUS_TYPE:
        for item in decoded.values:
            if item.key == STATUS_TIME_KEY:
                try:
                    seconds = float(item.value)
                except ValueError:
                    return None
                return round(seconds * 1e9) if math.isfinite(seconds) else None
    return None


def outcome_time_ns(msgtype: str, decoded: Any) -> int | None:
    """The simulated time of a goal's outcome, if this is a controller status that ends one."""
    if msgtype != STATUS_TYPE:
        return None
    values = {item.key: item.value for item in decoded.values}
    if OUTCOME_KEY not in values:
        return None
    return event_time_ns(msgtype, b'', decoded)


@dataclass
class Ordered:
    """What ``in_bag_order`` kept and left out."""

    counts: dict[str, int] = field(default_factory=dict)     # kept, per topic
    after_end: int = 0               # received, but after the end the run defines
    undecodable: int = 0             # did not decode as their type (damaged bytes)
    end_ns: int | None = None        # where the bag ends (None: at its last message)

    @property
    def kept(self) -> int:
        return sum(self.counts.values())


@dataclass(order=True)
class _Entry:
    time_ns: int
    rank: tuple[int, str]
    index: int
    topic: str = field(compare=False)
    msgtype: str = field(compare=False)
    data: bytes | None = field(compare=False)   # None: an image, read again when written


def _rank(topic: str) -> tuple[int, str]:
    """Where a topic comes within an instant: by TOPIC_ORDER (a fleet robot's topic
    where the single robot's is), then by name (robot_0's before robot_1's; two topics of one
    rank never left to the order they arrived in)."""
    own = robot_and_topic(topic)[1]
    return (TOPIC_ORDER.index(own) if own in TOPIC_ORDER else len(TOPIC_ORDER), topic)


def in_bag_order(read: Callable[[], Iterable[Stored]], typestore: Any,
                 end: str = 'outcome') -> tuple[Iterator[Stored], Ordered]:
    """The messages ``read()`` yields (in arrival order), as a finished bag holds them.

    ``end``: 'outcome' (the last outcome plus BAG_TAIL_S; everything when there is none),
    'recovered' (RECOVERY_WINDOW_S before the latest message) or 'all'. ``read`` is called a
    second time for the images, which are not kept in memory (a megabyte each). The report is
    complete once the iterator is exhausted.
    """
    report = Ordered()
    entries: list[_Entry] = []
    last_time: dict[str, int] = {}
    next_index: dict[str, int] = {}
    outcome_ns: int | None = None
    for topic, msgtype, log_time, data in read():
        try:
            decoded = typestore.deserialize_cdr(data, msgtype)
            canonical = bytes(typestore.serialize_cdr(decoded, msgtype))
        except Exception:   # whatever damaged bytes make a decoder raise
            report.undecodable += 1
            continue
        at = event_time_ns(msgtype, canonical, decoded)
        if at is None or (is_wall_clock(log_time * 1e-9) and not is_wall_clock(at * 1e-9)):
            at = log_time   # says none, or a time from 0 in a bag on the wall clock (a status
            # before a real robot's first state says 0): kept where it arrived
        at = max(at, last_time.get(topic, -2**63))
        last_time[topic] = at
        index = next_index.get(topic, 0)
        next_index[topic] = index + 1
        image = msgtype in IMAGE_TYPES
        entries.append(_Entry(at, _rank(topic), index, topic, msgtype,
                              None if image else canonical))
        finished_at = outcome_time_ns(msgtype, decoded)
        if finished_at is not None:
            outcome_ns = finished_at if outcome_ns is None else max(outcome_ns, finished_at)
    if end == 'outcome' and outcome_ns is not None:
        report.end_ns = outcome_ns + round(BAG_TAIL_S * 1e9)
    elif end == 'recovered' and entries:
        report.end_ns = max(entry.time_ns for entry in entries) - round(RECOVERY_WINDOW_S * 1e9)
    if report.end_ns is not None:
        kept = [entry for entry in entries if entry.time_ns <= report.end_ns]
        report.after_end = len(entries) - len(kept)
        entries = kept
    entries.sort()
    return _written(entries, read, typestore, report), report


def _written(entries: list[_Entry], read: Callable[[], Iterable[Stored]], typestore: Any,
             report: Ordered) -> Iterator[Stored]:
    images = _images(read, typestore, {(e.topic, e.index) for e in entries if e.data is None})
    for entry in entries:
        data = entry.data if entry.data is not None else images(entry.topic, entry.index)
        report.counts[entry.topic] = report.counts.get(entry.topic, 0) + 1
        yield entry.topic, entry.msgtype, entry.time_ns, data


def _images(read: Callable[[], Iterable[Stored]], typestore: Any,
            wanted: set[tuple[str, int]]) -> Callable[[str, int], bytes]:
    """Each wanted image, by topic and index, from a second reading: per topic in order, so
    only the few a topic is ahead of another are held at once."""
    if not wanted:
        return lambda topic, index: b''
    stream = iter(read())
    held: dict[str, deque[tuple[int, bytes]]] = {}
    seen: dict[str, int] = {}

    def image(topic: str, index: int) -> bytes:
        queue = held.setdefault(topic, deque())
        while not queue or queue[0][0] < index:
            if queue:
                queue.popleft()
                continue
            stored_topic, msgtype, _, data = next(stream)
            if msgtype not in IMAGE_TYPES:
                continue
            try:
                decoded = typestore.deserialize_cdr(data, msgtype)
            except Exception:
                continue   # left out on the first reading too: not counted
            number = seen.get(stored_topic, 0)
            seen[stored_topic] = number + 1
            if (stored_topic, number) in wanted:
                held.setdefault(stored_topic, deque()).append(
                    (number, bytes(typestore.serialize_cdr(decoded, msgtype))))
        return queue.popleft()[1]
    return image

