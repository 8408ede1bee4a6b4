"""``bag_recorder``: raw messages of the graph's topics into a rosbag2 bag.

While the run goes it is what ``ros2 bag record --use-sim-time`` would be: raw (still
serialized) messages, each stamped with the simulated time at which it arrived (on the bench,
``log_clock: wall``: the system clock, as ``ros2 bag record`` without it), into an mcap
(default) or sqlite3 bag with metadata version 9. Every 0.5 s of wall time the data written so
far is pushed to the file, so a SIGKILL loses at most that much (recover with
``omni-micro bag-recover``). When it stops it finishes the bag (:mod:`omni_micro_tools.bag_order`):
each message at the simulated time it belongs to, in one order, serialized canonically, ending
0.5 s after the run's last outcome; so the same run records the same file, byte for byte.

Parameters (its section of omni_micro_bringup's ``config/omni_micro.yaml``): ``bag`` (the folder to
create; required, must not exist), ``storage`` (mcap or sqlite3), ``topics`` (default: every topic
of the graph but the images; in a fleet each robot's under its namespace,
``/robot_k/odom``), ``lockstep_frames`` (report written frames on /lockstep, so that a
graph in lockstep waits for the disk as for its tracker), ``lockstep_ticks`` (report how far
every tick topic is recorded on /lockstep, so that a graph in lockstep never runs so far ahead
that a writer drops a sample before the recorder has it), ``end_at_outcome`` (false: keep every
message received, for a soak that counts them), ``log_clock`` (sim: /clock; wall: the system
clock, for a run with a real robot, which has no /clock), ``driver_images`` (a camera driver's
image topics, any names, each with the ``camera_info`` beside it, read best effort).
``omni-micro record`` and ``run --record`` start it.
"""

from __future__ import annotations

import contextlib
import struct
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMessage

from omni_micro_common.cdr import header_stamp_ns
from omni_micro_common.clocks import describe_clock, is_wall_clock
from omni_micro_common.errors import ParameterError
from omni_micro_common.lockstep import Ack
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.messages import message_class
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.qos import DATA_QOS, PER_TICK_SUBSCRIPTION_EVENTS, latched
from omni_micro_common.reader_matching import node_list_parameter
from omni_micro_common.topic_names import (
    CLOCK_TOPIC,
    GOAL_TOPIC,
    JOINT_STATES_TOPIC,
    MARKERS_TOPIC,
    ODOM_TOPIC,
    RECORDER_STATUS_TOPIC,
    WHEEL_SLIP_TOPIC,
)
from omni_micro_tools.bag_order import Ordered, marker_array_stamp_ns
from omni_micro_tools.bags import STORAGES, finish_in_order, flush, open_writer
from omni_micro_tools.errors import BagPathError
from omni_micro_tools.topics import (
    GRAPH_TOPICS,
    IMAGE_TOPICS,
    IMAGE_TYPES,
    RECEIVED_UP_TO_KEY,
    RECORDABLE_TOPICS,
    driver_image_topics,
    recordable_spec,
    robot_and_topic,
)

# Where the log time of a message comes from: the simulated clock on /clock, or the system clock
# (the bench: a real robot has no /clock).
LOG_CLOCKS = ('sim', 'wall')

# Data written so far is pushed to the file this often: a SIGKILL loses at most this much.
FLUSH_PERIOD_S = 0.5


RECORDER_DEPTH = 1000
# The robot's per-tick streams (each robot's, in a fleet): the recorder says how far it
# has received all of them (RECEIVED_UP_TO_KEY of /bag_recorder/status), so that whoever stops
# the graph knows the bag has everything up to a time. Each comes from one writer, in order.
TICK_TOPICS = (CLOCK_TOPIC, ODOM_TOPIC, JOINT_STATES_TOPIC, WHEEL_SLIP_TOPIC)
# Those of every tick (not /wheel_slip, every fifth): how far they are recorded is the
# recorder's lockstep report (lockstep_ticks), which must advance each tick.
EVERY_TICK_TOPICS = (CLOCK_TOPIC, ODOM_TOPIC, JOINT_STATES_TOPIC)
# Drawn from the odometry a little behind it (markers_node, outside the lockstep's gates): on
# the simulated clock they count in how far the recorder has received, so that a graph stopped
# once the recorder is past the bag's end has every array up to it in the bag (a composed fleet
# at twice real time, its markers_node behind on a busy machine, lost its last three arrays
# when the recorder went with only the ticks in). On the wall clock (the bench) nothing says
# they come on: they are left out.
DRAWN_TOPICS = (MARKERS_TOPIC,)
# Reported every five ticks of the default grid, half the lead the lockstep gives a recorder
# (omni_micro_common.lockstep.RECORDER_LEAD_TICKS): a report each tick made a recorded Fig. 11
# run in separate processes 25-40 % slower (1.43-1.88 s against 1.23-1.27 s without reports);
# every five, its median is 1.23 s again (1.07-2.08 s, 7 runs; measured).
RECORDED_REPORT_NS = 100_000_000


class BagRecorder(Node):
    """Writes each message as it arrives, stamped with the simulated time of its arrival."""

    def __init__(self, **node_options: Any) -> None:
        super().__init__('bag_recorder', **node_options)
        bag = Path(self.declare_parameter('bag', '').value)
        storage = self.declare_parameter('storage', 'mcap').value
        names = list(self.declare_parameter('topics', list(GRAPH_TOPICS)).value)
        lockstep_frames = bool(self.declare_parameter('lockstep_frames', False).value)
        self.lockstep_ticks = bool(self.declare_parameter('lockstep_ticks', False).value)
        self.end_at_outcome = bool(self.declare_parameter('end_at_outcome', True).value)
        log_clock = self.declare_parameter('log_clock', 'sim').value
        driver_images = node_list_parameter(self, 'driver_images')
        if str(bag) in ('', '.'):
            raise ParameterError('bag must name the folder to record into, got none')
        if storage not in STORAGES:
            raise ParameterError(f'storage must be one of {sorted(STORAGES)}, got {storage!r}')
        unknown = [name for name in names if recordable_spec(name) is None]
        if unknown or not names:
            raise ParameterError(f'topics must be some of {sorted(RECORDABLE_TOPICS)}, or a '
                                 f'fleet robot\'s (/robot_1/odom), got {names}')
        if bag.exists():
            raise ParameterError(f'bag {str(bag)!r} exists already: not recording over it')
        if log_clock not in LOG_CLOCKS:
            raise ParameterError(f'log_clock must be one of {list(LOG_CLOCKS)}, got '
                                 f'{log_clock!r}')
        topics = {name: spec for name in names if (spec := recordable_spec(name)) is not None}
        try:
            driver_topics = driver_image_topics(driver_images)
        except ValueError as error:
            raise ParameterError(f'driver_images: {error}') from None
        topics.update(driver_topics)
        # A driver publishes whether anyone runs or not: its first frame in the bag, not only its
        # discovery, says the log has the scene from before the goal (a bench log on a busy
        # machine lacked the driver's frames of its first 2 s, whose captures it had).
        self._first_frame_awaited = [topic for topic in driver_topics
                                     if topic.endswith('image_raw')]
        self.wall_clock = log_clock == 'wall'
        self.bag = bag
        self.storage = storage
        self.topics = topics
        # What finishing the bag kept (None: not finished; it stays in arrival order).
        self.finished: Ordered | None = None
        self.finish_failure: str | None = None
        self.writer, self.connections = open_writer(bag, storage, topics)
        self.counts = dict.fromkeys(topics, 0)
        self._closed = False
        # Why writing stopped (a full disk, a removed drive): the bag keeps what was written.
        self.write_failure: str | None = None
        # With lockstep_frames, the latest frame written per image and CameraInfo topic (see
        # _report_frame). A frame's CameraInfo counts as its image does: left out of the wait, one
        # was lost from an idle run's bag (its writer keeps 10, and a sample the transport
        # dropped is resent only while kept), and the same seed gave another file.
        self._frames_written: dict[str, int] = {}
        self.lockstep: LockstepReporter | None = None
        if lockstep_frames:
            self._frames_written = {topic: -1 for topic in topics if topic in IMAGE_TOPICS}
        if lockstep_frames or self.lockstep_ticks:
            self.lockstep = LockstepReporter(self)
        for topic, spec in topics.items():
            # A deep history on the reader's side whatever the topic's own depth: a latched
            # topic of depth 1 (a status) lost a message that came right after another before
            # the recorder took it (a replay at 20x).
            # A camera driver's images, recorded outside the lockstep, are read best effort: that
            # meets a reliable and a best-effort driver alike (REP-2003), as rosbag2 adapts to
            # what a publisher offers. In the lockstep no frame may be lost: reliable.
            best_effort = spec.msgtype in IMAGE_TYPES and not lockstep_frames
            qos = spec.reader_profile(max(spec.depth, RECORDER_DEPTH), best_effort)
            # Per-tick streams without QoS-event handlers, as in the nodes (omni_micro_common.qos).
            quiet = PER_TICK_SUBSCRIPTION_EVENTS if spec.depth >= 1000 else None
            self.create_subscription(message_class(spec.msgtype), topic, self._writer_of(topic),
                                     qos, raw=True, event_callbacks=quiet)
        # Simulated time, from the /clock messages themselves (what use_sim_time would give,
        # without a second /clock subscription per tick).
        self._clock_ns = 0
        self._other_clock_said = False
        if CLOCK_TOPIC not in topics:
            self.create_subscription(ClockMessage, CLOCK_TOPIC, self._on_clock, DATA_QOS,
                                     raw=True, event_callbacks=PER_TICK_SUBSCRIPTION_EVENTS)
        self._watched = [sub for sub in self.subscriptions
                         if sub.topic_name in topics and sub.topic_name != GOAL_TOPIC]
        self.status_pub = self.create_publisher(DiagnosticStatus, RECORDER_STATUS_TOPIC,
                                                latched(1))
        self._announced = False
        # The latest stamp received per topic that counts in how far the recorder has received
        # (the ticks' and, simulated, the drawn markers': _stamp_reader), and what was last said
        # of their minimum.
        self._received_stamps_ns = {topic: -1 for topic in topics if self._stamp_reader(topic)}
        self._said_up_to_ns = -1
        self._every_tick = [topic for topic in self._received_stamps_ns
                            if robot_and_topic(topic)[1] in EVERY_TICK_TOPICS]
        self._reported_ns = -1
        self._last_flush = time.monotonic()
        self.create_timer(0.1, self._on_wall_timer, clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(f'recording {len(topics)} topics into {bag} ({storage})')

    def _on_clock(self, data: bytes) -> None:
        sec, nanosec = struct.unpack_from('<iI', data, 4)   # after the CDR encapsulation
        clock_ns = sec * 1_000_000_000 + nanosec
        if self._clock_ns and is_wall_clock(clock_ns * 1e-9) != is_wall_clock(
                self._clock_ns * 1e-9):
            # One message of another clock would place every later one at its time (the bag's
            # order keeps a message where it was logged when its stamp is on another clock).
            if not self._other_clock_said:
                self._other_clock_said = True
                self.get_logger().warning(
                    f'/clock said {describe_clock(clock_ns * 1e-9)} after '
                    f'{describe_clock(self._clock_ns * 1e-9)}: another graph publishes /clock '
                    'on this domain? The bag keeps its messages but logs by the first clock')
            return
        started = self._clock_ns == 0 < clock_ns
        self._clock_ns = max(self._clock_ns, clock_ns)
        if started and self.write_failure is None:
            # What was said before the robot's clock started (its goal, each node's first
            # status) is on disk before the robot moves, whenever the last flush was.
            self._flush()

    def _stamp_reader(self, topic: str) -> Callable[[bytes], int | None] | None:
        """How to read the stamp of ``topic``'s raw messages, if it counts in how far the
        recorder has received: a tick topic's; on the simulated clock, a drawn topic's."""
        kind = robot_and_topic(topic)[1]
        if kind in TICK_TOPICS:
            return header_stamp_ns
        if kind in DRAWN_TOPICS and not self.wall_clock:
            return marker_array_stamp_ns
        return None

    def _writer_of(self, topic: str) -> Callable[[bytes], None]:
        connection = self.connections[topic]
        clock = topic == CLOCK_TOPIC
        stamp_of = self._stamp_reader(topic)

        def on_message(data: bytes) -> None:
            if clock:
                self._on_clock(data)
            if self.write_failure is not None:
                return
            try:
                self.writer.write(connection,
                                  time.time_ns() if self.wall_clock else self._clock_ns, data)
            except OSError as error:
                self._writing_failed(error)
                return
            self.counts[topic] += 1
            stamp_ns = stamp_of(data) if stamp_of is not None else None
            if stamp_ns is not None:
                self._received_stamps_ns[topic] = stamp_ns
                if self.lockstep_ticks:
                    self._report_recorded()
            if topic in self._frames_written:
                self._report_frame(topic, data)
        return on_message

    def _report_recorded(self, force: bool = False) -> None:
        """How far every tick's stream is in the bag (``recorded_ns``), when that has moved on:
        the lockstep keeps the robot within RECORDER_LEAD_TICKS of it, so that no writer drops
        a sample before the recorder has it. Not after a write failure: the run stops then."""
        up_to = max(0, min((self._received_stamps_ns[topic] for topic in self._every_tick),
                           default=-1))
        if self.write_failure is None and (
                force or self._reported_ns < 0 or up_to >= self._reported_ns + RECORDED_REPORT_NS):
            self._reported_ns = up_to
            assert self.lockstep is not None
            self.lockstep.report(Ack(self.get_name(), None, recorded_ns=up_to))

    def _report_frame(self, topic: str, data: bytes) -> None:
        """Frames are written up to the oldest of every camera stream's latest: the lockstep then
        waits for the disk as for a tracker. The stamp is read from the raw CDR (little-endian
        after the 4-byte encapsulation: header.stamp.sec, .nanosec first)."""
        sec, nanosec = struct.unpack_from('<iI', data, 4)
        self._frames_written[topic] = sec * 1_000_000_000 + nanosec
        assert self.lockstep is not None
        self.lockstep.report(Ack(self.get_name(), None,
                                 frame_handled_ns=min(self._frames_written.values())))

    def _writing_failed(self, error: OSError) -> None:
        """Stop writing and say why, once: on /bag_recorder/status (the orchestrator stops the
        run) and in the log. What was written stays in the bag, without metadata.yaml."""
        self.write_failure = f'cannot write {str(self.bag)!r}: {error.strerror or error}'
        self.get_logger().error(f'{self.write_failure}; recording stopped')
        self.status_pub.publish(DiagnosticStatus(
            level=DiagnosticStatus.ERROR, name='bag_recorder', message='write failed',
            values=[KeyValue(key='reason', value=self.write_failure)]))

    def _flush(self) -> None:
        try:
            flush(self.writer)
        except OSError as error:
            self._writing_failed(error)
        self._last_flush = time.monotonic()

    def _on_wall_timer(self) -> None:
        if self.write_failure is None and time.monotonic() - self._last_flush >= FLUSH_PERIOD_S:
            self._flush()
        # "recording" once every recorded topic has a matched publisher (and a driver's images a
        # frame written), so that whoever starts the graph's clock knows nothing will be missed
        # from the beginning.
        if not self._announced and all(sub.get_publisher_count() > 0 for sub in self._watched) \
                and all(self.counts[topic] for topic in self._first_frame_awaited):
            self._announce()
            self._announced = True
        up_to = min(self._received_stamps_ns.values(), default=-1)
        if self._announced and self.write_failure is None and up_to > self._said_up_to_ns:
            self._said_up_to_ns = up_to
            self._announce()
        if self._announced and self.lockstep_ticks:
            # Also on the wall clock: until its first report the robot waits for it at the lead,
            # and a report sent before the robot's reader matched is followed by no other.
            self._report_recorded(force=True)

    def _announce(self) -> None:
        """'recording', and how far every tick topic has been received."""
        self.status_pub.publish(DiagnosticStatus(
            level=DiagnosticStatus.OK, name='bag_recorder', message='recording',
            values=[KeyValue(key=RECEIVED_UP_TO_KEY, value=repr(self._said_up_to_ns * 1e-9))]))

    def close(self) -> None:
        """Write metadata.yaml: the bag is complete (once; later calls do nothing). After a
        write failure the bag stays as written (bag-recover reads it)."""
        if self._closed:
            return
        self._closed = True
        if self.write_failure is not None:
            with contextlib.suppress(OSError):
                self.writer.close()
            return
        try:
            self.writer.close()
        except OSError as error:
            self._writing_failed(error)
            return
        try:
            self.finished = finish_in_order(self.bag, self.storage, self.topics,
                                            whole=not self.end_at_outcome)
        except OSError as error:
            # The bag stays complete, in arrival order: readable, only not the same every run.
            self.finish_failure = (f'could not put {str(self.bag)!r} in the order of simulated '
                                   f'time ({error.strerror or error}): it stays as received')


def report_and_close(recorder: BagRecorder) -> None:
    recorder.close()
    if recorder.write_failure is not None:
        print(f'{recorder.write_failure}; {sum(recorder.counts.values())} messages taken '
              'before it: what reached the disk can be recovered with omni-micro bag-recover '
              f'{recorder.bag} --out DIR', file=sys.stderr)
        return
    if recorder.finish_failure is not None:
        print(recorder.finish_failure, file=sys.stderr)
    finished = recorder.finished
    counts = recorder.counts if finished is None else finished.counts
    tail = ''
    if finished is not None and finished.after_end and finished.end_ns is not None:
        tail = (f' ({finished.after_end} received after its end, '
                f'{finished.end_ns * 1e-9:.3f} s, left out)')
    print(f'recorded {sum(counts.values())} messages into {recorder.bag}{tail}: '
          + ', '.join(f'{topic} {counts.get(topic, 0)}' for topic in recorder.counts),
          file=sys.stderr)


# The node runtime stops it on Ctrl-C, SIGTERM or its orchestrator's death: first it takes what
# is still waiting in its readers (stopped last, it lags behind the graph on a busy machine: a
# composed run's bag once lacked its last 0.2 s of slip and captures), then it closes the bag
# (metadata.yaml written) and ends the process.
COMPONENT = NodeComponent(BagRecorder, config_errors=(BagPathError,),
                          on_shutdown=report_and_close,
                          drain=lambda recorder: sum(recorder.counts.values()))


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
