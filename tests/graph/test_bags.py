"""Bags: what a recorded run holds (read by rosbags and, independently, by mcap-ros2-support),
analysis from the bag alone, a replay round trip, and recovery after a real SIGKILL."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from conftest import SHARED_SEED
from nav_msgs.msg import Odometry
from rclpy.qos import QoSProfile, ReliabilityPolicy

from omni_micro_bringup.processes import node_environment
from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.bags import GRAPH_TOPICS

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope='module')
def recorded(fig11_recorded):
    """The shared Fig. 11 run, recorded (read only: every test here reads it)."""
    return fig11_recorded


def test_metadata_is_rosbag2_version_9_with_types_counts_and_qos(recorded):
    bag, summary = recorded
    info = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    topics = {t['topic_metadata']['name']: t for t in info['topics_with_message_count']}
    assert set(topics) == set(GRAPH_TOPICS)
    for name, spec in GRAPH_TOPICS.items():
        metadata = topics[name]['topic_metadata']
        assert metadata['type'] == spec.msgtype
        qos = metadata['offered_qos_profiles'][0]
        assert qos['reliability'] == 'reliable' and qos['depth'] == spec.depth
        assert qos['durability'] == ('transient_local' if spec.latched else 'volatile')
        assert topics[name]['message_count'] > 0
    # Simulated time: the run starts at 0 and lasts tens of seconds, not since 1970.
    assert info['starting_time']['nanoseconds_since_epoch'] < 10**9
    assert summary['sim_time_s'] * 1e9 < info['duration']['nanoseconds'] < 10**11


def test_the_recorded_qos_is_what_the_graphs_publishers_offer(tmp_path):
    """The metadata above is written from omni_micro_tools.topics' table; this checks the table
    against the publishers a running graph really has (read from the ROS graph, as rqt_graph
    would), so that a publisher whose QoS changes makes the bag's metadata fail here."""
    from omni_micro_bringup.graph_description import describe_graph
    from omni_micro_bringup.graph_options import GraphOptions

    described = describe_graph(GraphOptions(goal_m=(0.1, 0.0), log_dir=tmp_path / 'logs',
                                            record=tmp_path / 'bag'))
    offered = {topic.topic: topic.publishers for topic in described}
    for name, spec in GRAPH_TOPICS.items():
        assert offered.get(name), f'nobody publishes {name}'
        expected = ('reliable', 'transient_local' if spec.latched else 'volatile')
        for publisher in offered[name]:
            assert (publisher.reliability, publisher.durability) == expected, (name, publisher)


def test_an_independent_mcap_reader_decodes_the_same_messages(recorded):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    bag, summary = recorded
    ours = read_bag(bag)
    counts: dict[str, int] = {}
    odometry = []
    moves = 0
    with open(next(bag.glob('*.mcap')), 'rb') as stream:
        reader = make_reader(stream, decoder_factories=[DecoderFactory()])
        for _, channel, _, decoded in reader.iter_decoded_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == '/odom':
                odometry.append(decoded)
            if channel.topic == '/wheel_trajectory' and decoded.points:
                moves += 1
    assert counts == {topic: len(raw) for topic, raw in ours.raw.items()}
    assert moves == summary['periods']
    # The robot is at rest to ~1e-13 m/s after the goal; the bag goes on a few seconds longer.
    final = odometry[-1].pose.pose.position
    assert final.x * 1e3 == pytest.approx(summary['final_x_mm'], abs=1e-6)
    assert final.y * 1e3 == pytest.approx(summary['final_y_mm'], abs=1e-6)
    assert odometry[-1].header.frame_id == 'odom'


def test_analyze_draws_and_summarises_from_the_bag_alone(recorded, tmp_path, omni_micro):
    bag, summary = recorded
    out = tmp_path / 'analysis'
    result = omni_micro('analyze', str(bag), '--out', str(out))
    assert result.returncode == 0, result.stderr
    for name in ('route.png', 'slip_longitudinal.png', 'slip_transverse.png', 'periods.png'):
        assert (out / name).stat().st_size > 10_000
    assert 'reached' in (out / 'summary.md').read_text()
    analysed = json.loads((out / 'summary.json').read_text())
    assert analysed['outcome'] == 'reached' and analysed['periods'] == summary['periods']
    assert analysed['deviation_mm'] == pytest.approx(summary['deviation_mm'], abs=1e-6)
    assert analysed['message_counts']['/goal_pose'] == 1


def test_existing_bag_is_refused_without_force(recorded, omni_micro, tmp_path):
    bag, _ = recorded
    result = omni_micro('run', '--goal-mm', '100,0', '--record', str(bag),
                        '--log-dir', str(tmp_path))
    assert result.returncode == 2 and 'exists already' in result.stderr
    assert (bag / 'metadata.yaml').is_file()
    plain = tmp_path / 'notes'
    plain.mkdir()
    (plain / 'important.txt').write_text('keep me')
    result = omni_micro('record', str(plain), '--force')
    assert result.returncode == 2 and 'not a bag' in result.stderr
    assert (plain / 'important.txt').read_text() == 'keep me'


def start_recorder(bag: Path, domain_id: int, *extra: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, '-m', 'omni_micro_cli', 'record', str(bag), '--domain-id',
         str(domain_id), *extra], cwd=ROOT, env=node_environment(domain_id, bag.parent),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def test_replay_round_trip_keeps_every_message(recorded, domain_id, tmp_path, omni_micro):
    bag, _ = recorded
    again = tmp_path / 'again'
    recorder = start_recorder(again, domain_id, '--storage', 'sqlite3')
    try:
        result = omni_micro('replay', str(bag), '--clock', '--rate', '20',
                            '--wait-subscribers', '30', '--domain-id', str(domain_id))
        assert result.returncode == 0, result.stderr
        time.sleep(1.0)
    finally:
        recorder.send_signal(signal.SIGINT)
        output = recorder.communicate(timeout=30)[0]
    assert recorder.returncode == 0, output
    original, replayed = read_bag(bag, decode=False), read_bag(again, decode=False)
    assert next(again.glob('*.db3'))
    for topic, messages in original.raw.items():
        assert replayed.raw[topic] == messages, topic


def test_replay_says_what_it_plays_and_an_interrupted_replay_exits_130(recorded, domain_id,
                                                                       tmp_path):
    """Ctrl-C (SIGINT) on a replay: exit 130 as every command interrupted, saying how far it
    went; before it, one line of what it plays and how long that takes at its --rate."""
    bag, _ = recorded
    replay = subprocess.Popen(
        [sys.executable, '-m', 'omni_micro_cli', 'replay', str(bag), '--rate', '0.05',
         '--domain-id', str(domain_id)], cwd=ROOT,
        env=node_environment(domain_id, tmp_path), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)
    try:
        assert replay.stderr is not None
        # Its own first line; Fast DDS may say first, on standard error too, that its participant
        # probed past a shared-memory port another process holds (`Failed init_port`: a
        # three-worker suite's replay met one).
        said = replay.stderr.readline()
        while 'RTPS_TRANSPORT_SHM' in said:
            said = replay.stderr.readline()
        match = re.match(r'replaying (\d+) messages on (\d+) topics from .*: ([\d.]+) s of the '
                         r'bag at --rate 0.05, about ([\d.]+) s$', said.strip())
        assert match, said
        total, span_s, wall_s = int(match[1]), float(match[3]), float(match[4])
        assert total > 100 and span_s > 5.0 and wall_s == pytest.approx(span_s / 0.05, rel=0.01)
        time.sleep(1.0)
        replay.send_signal(signal.SIGINT)
        _, rest = replay.communicate(timeout=30)
    finally:
        if replay.poll() is None:
            replay.kill()
            replay.wait()
    assert replay.returncode == 130, rest
    played = re.search(r'interrupted after (\d+) of (\d+) messages', rest)
    assert played and int(played[2]) == total and int(played[1]) < total, rest
    assert 'replay: interrupted' in rest


def test_a_killed_recorder_loses_at_most_its_last_flush_and_the_unsure_second(
        leftovers_removed, domain_id, probe, tmp_path, omni_micro):
    """SIGKILL: what the recorder had pushed to the file (every 0.5 s) comes back, but for the
    last second of the messages' own time, which bag-recover leaves out (it may have been
    incomplete): at most 2 s is lost (0.5 s left for a recorder behind a busy machine).
    Stamped on the wall clock, as a robot on the bench."""
    bag = tmp_path / 'killed'
    recorder = start_recorder(bag, domain_id, '--topics', '/odom')
    publisher = probe.node.create_publisher(
        Odometry, '/odom', QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    probe.spin_until(lambda: publisher.get_subscription_count() > 0, 30.0, 'the recorder')
    time.sleep(0.5)
    sent = []   # (wall time, index)
    started = time.monotonic()
    index = 0
    while time.monotonic() - started < 3.0:
        msg = Odometry()
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(
            round((time.monotonic() - started) * 1e9), 1_000_000_000)
        msg.pose.pose.position.x = float(index)
        publisher.publish(msg)
        sent.append((time.monotonic(), index))
        index += 1
        time.sleep(0.01)
    killed_at = time.monotonic()
    os.kill(recorder.pid, signal.SIGKILL)
    recorder.wait(10)
    assert not (bag / 'metadata.yaml').exists()          # a torn bag, as measured
    result = omni_micro('bag-recover', str(bag))
    assert result.returncode == 0, result.stderr
    assert 'left out the last 1 s of simulated time' in result.stderr
    recovered = read_bag(bag.with_name('killed-recovered'))
    kept = [m.pose.pose.position.x for m in recovered.messages['/odom']]
    must_have = [i for t, i in sent if t < killed_at - 2.0]
    assert kept[:len(must_have)] == [float(i) for i in must_have]
    assert kept == [float(i) for i in range(len(kept))]   # in order, nothing invented


def test_odometry_replayed_into_a_vision_node_gives_the_same_captures(
        recorded, start_node, probe, domain_id, busy_machine):
    """Feeding a node from a bag: the camera model is a function of the odometry and the seed,
    so the recorded /odom replayed into a fresh vision_node yields the recorded captures, even
    when the machine is too busy for the node to keep up with the replay's pace (--sync)."""
    from geometry_msgs.msg import PoseStamped

    bag, _ = recorded
    start_node('omni_micro_vision', 'vision_node', f'seed:={SHARED_SEED}')
    captures: list[PoseStamped] = []
    readers = [probe.node.create_subscription(
        PoseStamped, f'/camera/{camera}/pose', captures.append,
        QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        for camera in ('macro', 'micro')]
    # Captures are volatile: the probe must be matched to the camera before the first one goes
    # out (on a busy machine discovery takes longer than the replay's wait for /odom readers).
    probe.spin_until(lambda: all(r.get_publisher_count() > 0 for r in readers), 60.0,
                     "the probe matched to the vision_node's capture writers")
    # The probe spins while the replay runs: a capture writer keeps only its last 100.
    with busy_machine():
        replay = subprocess.Popen(
            [str(ROOT / 'scripts' / 'omni-micro'), 'replay', str(bag), '--topics', '/odom',
             '--rate', '10', '--wait-subscribers', '30', '--sync', 'vision_node',
             '--domain-id', str(domain_id)],
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        probe.spin_until(lambda: replay.poll() is not None, 240.0, 'the replay to finish')
    assert replay.returncode == 0, replay.communicate()[0]
    recorded_captures = read_bag(bag, topics=['/camera/macro/pose', '/camera/micro/pose'])
    expected = sorted((m.header.stamp.sec, m.header.stamp.nanosec, m.pose.position.x,
                       m.pose.position.y) for topic in recorded_captures.messages
                      for m in recorded_captures.messages[topic])
    probe.spin_for(2.0)
    got = sorted((m.header.stamp.sec, m.header.stamp.nanosec, m.pose.position.x,
                  m.pose.position.y) for m in captures)
    missing = sorted(set(expected) - set(got))
    assert not missing, f'{len(missing)} of {len(expected)} missing, first {missing[:3]}; ' \
                        f'got {len(got)}'


@pytest.mark.parametrize('synced', [True, False], ids=['sync', 'no-sync'])
def test_replay_waits_for_a_subscriber_that_cannot_keep_up(recorded, probe, domain_id, synced):
    """A slow node (10-deep queue, 2 ms per sample: the replay at --rate 200 sends one every
    0.1 ms) gets every /odom sample with --sync; without it the replay outruns the node and
    samples are lost (which shows the test can fail)."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
    from nav_msgs.msg import Odometry

    from omni_micro_common.lockstep import ACK_MESSAGE, ACK_TOPIC, Ack
    from omni_micro_common.lockstep_reporting import LOCKSTEP_QOS

    bag, _ = recorded
    reports = probe.node.create_publisher(DiagnosticStatus, ACK_TOPIC, LOCKSTEP_QOS)
    received = []

    def slow_node(msg: Odometry) -> None:
        time.sleep(0.002)
        received.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
        reports.publish(DiagnosticStatus(name='slow_node', message=ACK_MESSAGE, values=[
            KeyValue(key=k, value=v) for k, v in Ack('slow_node', received[-1]).to_values()]))

    probe.node.create_subscription(Odometry, '/odom', slow_node, QoSProfile(
        depth=10, reliability=ReliabilityPolicy.RELIABLE))
    replay = subprocess.Popen(
        [str(ROOT / 'scripts' / 'omni-micro'), 'replay', str(bag), '--topics', '/odom',
         '--rate', '200', '--wait-subscribers', '30', '--domain-id', str(domain_id)]
        + (['--sync', 'slow_node'] if synced else []),
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    probe.spin_until(lambda: replay.poll() is not None, 240.0, 'the replay to finish')
    assert replay.returncode == 0, replay.communicate()[0]
    probe.spin_for(1.0)
    expected = len(read_bag(bag, topics=['/odom']).messages['/odom'])
    if synced:
        assert len(received) == expected
    else:
        assert len(received) < expected
