"""The loop closed on rendered images (run --vision images): camera_node and tracker_node take
vision_node's place in the lockstep. The same seed gives the same bag file, images included,
idle, busy or composed; no frame is lost to the recorder; only the finest camera that sees the
robot captures; and the recorded images replayed into a fresh tracker_node give the recorded
captures again."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from bag_compare import bag_digest, recorded_until, stored_messages
from geometry_msgs.msg import PoseStamped

from omni_micro_bringup.graph import GraphResult, run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.params_files import dds_profile
from omni_micro_common.conventions import stamp_ns
from omni_micro_common.qos import CAPTURE_QOS
from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.topics import BAG_TAIL_S

IMAGE_TOPICS = ['/camera/macro/image_raw', '/camera/macro/camera_info',
                '/camera/micro/image_raw', '/camera/micro/camera_info']
FRAME_RATE_HZ = 30.0



@pytest.fixture(autouse=True)
def image_transport(monkeypatch):
    """Nodes and commands started here carry camera frames: the profile a graph with images
    gets (omni_micro_bringup.params_files.dds_profile)."""
    monkeypatch.setenv('FASTRTPS_DEFAULT_PROFILES_FILE', str(dds_profile()))

def run_on_images(folder: Path, name: str, composed: bool = False,
                  real_time_factor: float = math.inf) -> tuple[Path, GraphResult]:
    """A short run on the micro platform, images recorded, as fast as the lockstep allows.
    The bag is always called 'bag' (its file is named after it), in a folder ``name``."""
    bag = folder / name / 'bag'
    result = run_graph(GraphOptions(
        goal_m=(0.1005, 0.0004), seed=7, real_time_factor=real_time_factor, vision='images',
        record=bag, record_images=True, log_dir=folder / 'logs', composed=composed,
        dynamics_overrides={'initial_pose': [0.1, 0.0, 0.0]}))
    assert result.outcome == 'reached' and result.periods >= 2, result.reason
    return bag, result


@pytest.fixture(scope='module')
def idle_run(tmp_path_factory) -> tuple[Path, GraphResult]:
    return run_on_images(tmp_path_factory.mktemp('images'), 'idle')


def test_same_seed_same_file_with_images_idle_and_busy_and_no_frame_lost(
        idle_run, tmp_path, busy_machine):
    idle_bag, idle = idle_run
    with busy_machine():
        busy_bag, busy = run_on_images(tmp_path, 'busy')
    assert busy.sim_time_s == idle.sim_time_s
    assert bag_digest(busy_bag) == bag_digest(idle_bag)
    # Every frame up to the bag's end was recorded, however busy the recorder's disk and cores:
    # one each 1/30 s from time 0, the last less than a frame period before the end.
    end_ns = round(idle.sim_time_s * 1e9) + round(BAG_TAIL_S * 1e9)
    for topic in IMAGE_TOPICS:
        stamps = [time for stored, time, _ in stored_messages(idle_bag) if stored == topic]
        assert [round(k * 1e9 / FRAME_RATE_HZ) for k in range(len(stamps))] == stamps, topic
        assert 0 <= end_ns - stamps[-1] < 1e9 / FRAME_RATE_HZ, topic
    idle_messages = recorded_until(idle_bag, idle.sim_time_s)
    # The robot is in both fields; only the micro camera, the finer, captured.
    assert idle_messages['/camera/micro/pose'] and not idle_messages['/camera/macro/pose']
    assert 0.0 < idle.deviation_m < 3e-6


def test_same_seed_same_file_with_images_at_another_real_time_factor(idle_run, tmp_path):
    slow_bag, slow = run_on_images(tmp_path, 'slow', real_time_factor=2.0)
    assert slow.sim_time_s == idle_run[1].sim_time_s
    assert bag_digest(slow_bag) == bag_digest(idle_run[0])


def test_same_seed_same_file_with_images_and_the_loop_in_one_process(idle_run, tmp_path):
    composed_bag, composed = run_on_images(tmp_path, 'composed', composed=True)
    assert (composed.log_dir / 'loop_container.log').exists()
    assert bag_digest(composed_bag) == bag_digest(idle_run[0])


def test_recorded_images_replayed_into_a_fresh_tracker_give_the_recorded_captures(
        idle_run, start_node, probe, domain_id, omni_micro):
    bag, result = idle_run
    end_ns = round(result.sim_time_s * 1e9)
    # Up to the outcome: at shutdown the tracker may stop between a frame and its capture.
    recorded = [m for m in read_bag(bag, ['/camera/micro/pose']).messages['/camera/micro/pose']
                if m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec <= end_ns]
    captures: list[PoseStamped] = []
    reader = probe.node.create_subscription(PoseStamped, '/camera/micro/pose', captures.append,
                                            CAPTURE_QOS)
    # Reliable: at 100x a best-effort reader (the node's default, to meet any driver) may lose
    # frames, and this replay must reproduce every capture.
    start_node('omni_micro_vision', 'tracker_node', 'image_reliability:=reliable')
    # The replay waits for the tracker's image readers, not for this reader of its captures:
    # a capture sent before the two have matched would be lost to it (seen on a busy run).
    probe.spin_until(lambda: reader.get_publisher_count() >= 1, 30.0,
                     "the tracker's capture writer")
    replay = omni_micro('replay', str(bag), '--topics', *IMAGE_TOPICS, '--sync', 'tracker_node',
                        '--wait-subscribers', '30', '--rate', '100', '--domain-id',
                        str(domain_id))
    assert replay.returncode == 0, replay.stderr
    probe.spin_until(lambda: len(captures) >= len(recorded), 30.0, 'the captures')
    captures = [c for c in captures if stamp_ns(c.header.stamp) <= end_ns]
    # The images alone decide: the same captures, stamp and pose, and no other.
    assert [stamp_ns(c.header.stamp) for c in captures] == [
        m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec for m in recorded]
    for again, original in zip(captures, recorded, strict=True):
        assert again.pose.position.x == original.pose.position.x
        assert again.pose.position.y == original.pose.position.y
        assert again.pose.orientation.z == original.pose.orientation.z


def test_track_reads_the_recorded_images_offline_and_states_their_spread(
        idle_run, omni_micro, tmp_path):
    bag, _ = idle_run
    frames = len(read_bag(bag, ['/camera/micro/image_raw'], decode=False).raw[
        '/camera/micro/image_raw'])
    done = omni_micro('track', str(bag), '--csv', str(tmp_path / 'frames.csv'))
    assert done.returncode == 0, done.stderr
    assert f'micro camera, {frames} frames: fiducial found in {frames}, still' in done.stdout
    # The renderer's micro camera is far better than the model's 0.1 px: the advice says so.
    spread_line = next(line for line in done.stdout.splitlines() if line.startswith('spread'))
    measured_um = float(spread_line.split('x ')[1].split(' um')[0])
    assert 0.0 < measured_um < 0.115
    assert 'micro.quantisation_px: 0 ' in done.stdout
    assert len((tmp_path / 'frames.csv').read_text().splitlines()) == frames + 1
    wrong = omni_micro('track', str(bag), '--image-topic', '/usb_cam/image_raw')
    assert wrong.returncode == 2
    assert "no /usb_cam/image_raw: its image topics are ['/camera/macro/image_raw', " \
           "'/camera/micro/image_raw']" in wrong.stderr
