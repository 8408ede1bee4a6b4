"""A finished bag's order (omni_micro_tools.bag_order): messages received in any order come out
at the simulated time they belong to, in one order, canonically serialized, ending a fixed
time after the last outcome; finishing a finished bag changes no byte."""

from __future__ import annotations

import hashlib
import itertools
import random
from pathlib import Path

from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock

from omni_micro_common.conventions import STATUS_TIME_KEY
from omni_micro_tools.bag_reading import bag_message_counts, read_bag
from omni_micro_tools.bags import TYPESTORE, finish_in_order, open_writer
from omni_micro_tools.topics import BAG_TAIL_S, GRAPH_TOPICS, TopicSpec, recordable_spec

TICK_NS = 20_000_000
TOPICS = {topic: GRAPH_TOPICS[topic] for topic in ('/clock', '/odom', '/controller/status')}


def clock(tick: int) -> bytes:
    msg = Clock()
    msg.clock.sec, msg.clock.nanosec = divmod(tick * TICK_NS, 1_000_000_000)
    return serialize_message(msg)


def odometry(tick: int) -> bytes:
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(tick * TICK_NS, 1_000_000_000)
    msg.header.frame_id = 'odom'
    msg.pose.pose.position.x = tick * 1e-6
    return serialize_message(msg)


def status(message: str, at_tick: int, outcome: bool = False) -> bytes:
    values = [KeyValue(key=STATUS_TIME_KEY, value=repr(at_tick * TICK_NS * 1e-9))]
    if outcome:
        values.append(KeyValue(key='outcome', value=message))
    return serialize_message(DiagnosticStatus(name='omni_micro_controller', message=message,
                                              values=values))


def a_run(ticks: int, outcome_tick: int) -> list[tuple[str, bytes]]:
    """What a run publishes, per topic in publication order."""
    run = [('/clock', clock(t)) for t in range(1, ticks)]
    run += [('/odom', odometry(t)) for t in range(1, ticks)]
    run += [('/controller/status', status('moving', t)) for t in range(5, outcome_tick, 10)]
    run.append(('/controller/status', status('reached', outcome_tick, outcome=True)))
    return run


def recorded(path: Path, run: list[tuple[str, bytes]], seed: int,
             topics: dict[str, TopicSpec] = TOPICS) -> Path:
    """The run as a recorder receives it: each topic in its order, the topics interleaved at
    random, each stamped with an arrival time of its own."""
    rng = random.Random(seed)
    streams = {topic: [data for t, data in run if t == topic] for topic in topics}
    writer, connections = open_writer(path, 'mcap', topics)
    arrival = 0
    while any(streams.values()):
        topic = rng.choice([t for t, left in streams.items() if left])
        arrival += rng.randrange(1, 3 * TICK_NS)
        writer.write(connections[topic], arrival, streams[topic].pop(0))
    writer.close()
    return path


def stored_messages(bag: Path) -> list[tuple[str, int, bytes]]:
    """Topic, log time and bytes of every message, in the order the file holds them."""
    from mcap.reader import make_reader

    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        return [(channel.topic, message.log_time, message.data)
                for _, channel, message in make_reader(stream).iter_messages(
                    log_time_order=False)]


def digest(path: Path) -> str:
    return hashlib.sha256(next(path.glob('*.mcap')).read_bytes()).hexdigest()


def test_two_arrival_orders_give_one_file(tmp_path):
    run = a_run(ticks=100, outcome_tick=60)
    first = recorded(tmp_path / 'one' / 'bag', run, seed=1)
    second = recorded(tmp_path / 'two' / 'bag', run, seed=2)
    assert digest(first) != digest(second)      # as received: different
    finish_in_order(first, 'mcap', TOPICS)
    finish_in_order(second, 'mcap', TOPICS)
    assert digest(first) == digest(second)
    assert (first / 'metadata.yaml').read_text() == (second / 'metadata.yaml').read_text()
    # Finishing a finished bag changes no byte.
    before = digest(first)
    finish_in_order(first, 'mcap', TOPICS)
    assert digest(first) == before


def test_the_finished_bag_is_in_simulated_time_and_ends_a_tail_after_the_outcome(tmp_path):
    bag = recorded(tmp_path / 'bag', a_run(ticks=100, outcome_tick=60), seed=3)
    ordered = finish_in_order(bag, 'mcap', TOPICS)
    end_ns = 60 * TICK_NS + round(BAG_TAIL_S * 1e9)
    assert ordered.end_ns == end_ns
    read = read_bag(bag)
    assert read.timestamps['/clock'] == list(range(TICK_NS, end_ns + 1, TICK_NS))
    # What the bag's index counts (the soak's check against what was published) is what it
    # holds, the messages past its end left out of both.
    assert bag_message_counts(bag) == {topic: len(stamps)
                                       for topic, stamps in read.timestamps.items()}
    assert bag_message_counts(bag)['/clock'] == end_ns // TICK_NS
    assert read.timestamps['/odom'] == read.timestamps['/clock']
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            for m in read.messages['/odom']] == read.timestamps['/odom']
    # Each status at its own time, the outcome last.
    assert read.timestamps['/controller/status'] == [*range(5 * TICK_NS, 60 * TICK_NS,
                                                             10 * TICK_NS), 60 * TICK_NS]
    assert ordered.after_end == 2 * (99 - end_ns // TICK_NS)
    # Within one instant, the clock before the odometry before the status (TOPIC_ORDER).
    stored = stored_messages(bag)
    at_60 = [topic for topic, time, _ in stored if time == 60 * TICK_NS]
    assert at_60 == ['/clock', '/odom', '/controller/status']
    times = [time for _, time, _ in stored]
    assert times == sorted(times)


def test_a_fleet_bag_holds_each_instant_robot_by_robot_whatever_the_arrival(tmp_path):
    """Each robot's topics rank where the single robot's do, then by robot: two robots'
    odometry of one tick never stays in the order it happened to arrive in."""
    topics = {topic: spec for topic in ('/clock', '/robot_0/odom', '/robot_1/odom',
                                        '/robot_0/controller/status')
              if (spec := recordable_spec(topic)) is not None}
    run = [('/clock', clock(t)) for t in range(1, 80)]
    run += [(f'/robot_{k}/odom', odometry(t)) for k in (0, 1) for t in range(1, 80)]
    run += [('/robot_0/controller/status', status('reached', 30, outcome=True))]
    bags = [recorded(tmp_path / str(seed) / 'bag', run, seed, topics) for seed in range(3)]
    for bag in bags:
        finish_in_order(bag, 'mcap', topics)
    assert len({digest(bag) for bag in bags}) == 1
    at_30 = [topic for topic, time, _ in stored_messages(bags[0]) if time == 30 * TICK_NS]
    assert at_30 == ['/clock', '/robot_0/odom', '/robot_1/odom', '/robot_0/controller/status']
    # The robot's outcome ends the bag as the single robot's does.
    assert read_bag(bags[0]).timestamps['/clock'][-1] == 30 * TICK_NS + round(BAG_TAIL_S * 1e9)


def test_padding_a_publisher_left_dirty_is_written_as_zeros(tmp_path):
    """The bytes between fields are not the message, and rclpy's serializer leaves there
    whatever its buffer held (seen: bytes 21, 29 and 32-35 of an Odometry). Publications of one
    message that differ only there are stored alike, as rosbags serializes it."""
    published = odometry(7)
    canonical = bytes(TYPESTORE.serialize_cdr(
        TYPESTORE.deserialize_cdr(published, 'nav_msgs/msg/Odometry'), 'nav_msgs/msg/Odometry'))
    owned = TYPESTORE.deserialize_cdr(canonical, 'nav_msgs/msg/Odometry')
    padding = [i for i in range(4, len(canonical)) if _same_message(canonical, i, owned)]
    assert padding, 'an Odometry has alignment padding'
    dirty = bytearray(canonical)
    for index in padding:
        dirty[index] = 0xAB
    paths = []
    for name, data in (('published', published), ('dirty', bytes(dirty))):
        writer, connections = open_writer(tmp_path / name / 'bag', 'mcap',
                                          {'/odom': GRAPH_TOPICS['/odom']})
        writer.write(connections['/odom'], 1, data)
        writer.close()
        finish_in_order(tmp_path / name / 'bag', 'mcap', {'/odom': GRAPH_TOPICS['/odom']})
        paths.append(tmp_path / name / 'bag')
    for path in paths:
        assert read_bag(path, decode=False).raw['/odom'] == [canonical]
    assert digest(paths[0]) == digest(paths[1])


def _same_message(data: bytes, index: int, decoded: object) -> bool:
    changed = bytearray(data)
    changed[index] ^= 0xFF
    try:
        again = TYPESTORE.deserialize_cdr(bytes(changed), 'nav_msgs/msg/Odometry')
    except Exception:
        return False
    return repr(again) == repr(decoded)


def test_topics_of_one_instant_keep_their_publication_order_within_a_topic(tmp_path):
    """Two statuses of one time (a goal accepted and a move at once) stay in the order they
    were published, whatever else came between them."""
    run = [('/clock', clock(t)) for t in range(1, 20)]
    run += [('/controller/status', status(name, 10)) for name in ('settling', 'moving')]
    for seed in range(3):
        bag = recorded(tmp_path / str(seed) / 'bag', run, seed)
        finish_in_order(bag, 'mcap', TOPICS, whole=True)
        messages = read_bag(bag).messages['/controller/status']
        assert [m.message for m in messages] == ['settling', 'moving']
    assert len({digest(tmp_path / str(seed) / 'bag') for seed in range(3)}) == 1
    assert list(itertools.islice(read_bag(bag).timestamps['/clock'], 2)) == [TICK_NS,
                                                                             2 * TICK_NS]


def test_on_the_wall_clock_a_status_said_at_time_0_stays_where_it_came(tmp_path):
    """A bench run's bag (log times and stamps on the wall clock): the controller's first
    status, said before the real robot's first state, is stamped 0; placed there it would come
    1.8e9 s before the run (a replay then slept for ever). It keeps its arrival time; a status
    on the wall clock keeps its own."""
    wall_ns = 1_796_000_000 * 10**9
    writer, connections = open_writer(tmp_path / 'bag', 'mcap', TOPICS)
    writer.write(connections['/controller/status'], wall_ns + 5, status('idle', 0))
    said_at = serialize_message(DiagnosticStatus(message='moving', values=[
        KeyValue(key=STATUS_TIME_KEY, value=repr((wall_ns + 3 * TICK_NS) * 1e-9))]))
    writer.write(connections['/controller/status'], wall_ns + 9 * TICK_NS, said_at)
    writer.close()
    finish_in_order(tmp_path / 'bag', 'mcap', TOPICS)
    times = [log_time for _, log_time, _ in stored_messages(tmp_path / 'bag')]
    assert times[0] == wall_ns + 5
    assert abs(times[1] - (wall_ns + 3 * TICK_NS)) < 1000   # its own time, to a microsecond
