"""The servo mode through the graph (`run --controller servo`): Fig. 11's goal reached as the twin
reaches it, with the same plans made while rolling from the same captures in motion, and on the
rendered images through the tracker; the same seed records the same bag at another speed with both
cores kept busy, and with the loop in one process (the lockstep waits for every capture in motion
the controller acts on: docs/control.md, "The servo mode")."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import pytest
from bag_compare import bag_digest
from conftest import ROOT

from omni_micro_bringup.graph import GraphResult, run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_common.conventions import stamp_ns
from omni_micro_common.topic_names import CAPTURE_IN_MOTION_TOPICS, ODOM_TOPIC
from omni_micro_control.servo_config import ServoConfig
from omni_micro_sim import paper
from omni_micro_studies.twin import run_servo
from omni_micro_tools.bag_reading import read_bag

SEED = 3
TOLERANCE_M = 0.5e-6


def servo_run(folder: Path, real_time_factor: float = math.inf, vision: str = 'model',
              composed: bool = False) -> tuple[Path, GraphResult]:
    bag = folder / 'bag'
    result = run_graph(GraphOptions(
        goal_m=paper.FIG11_GOAL_M, seed=SEED, real_time_factor=real_time_factor, record=bag,
        log_dir=folder / 'logs', vision=vision, composed=composed,
        controller_overrides={'mode': 'servo', 'tolerance_m': TOLERANCE_M}))
    # No command arrives after its start stamp, plans made while rolling included.
    log = 'loop_container.log' if composed else 'dynamics_node.log'
    assert 'arrived' not in (result.log_dir / log).read_text()
    return bag, result


@pytest.fixture(scope='module')
def reference(tmp_path_factory) -> tuple[Path, GraphResult]:
    return servo_run(tmp_path_factory.mktemp('servo'))


def test_the_servo_over_the_graph_is_the_twin(reference):
    _, graph = reference
    twin = run_servo(paper.FIG11_GOAL_M, robot=paper.FIG11_OPEN_LOOP.robot(), seed=SEED,
                     config=ServoConfig(tolerance_m=TOLERANCE_M))
    assert graph.outcome == twin.outcome.value == 'reached'
    assert graph.periods == twin.periods == 1 and graph.sim_time_s <= 8.0
    assert graph.final_x_m == pytest.approx(twin.final_state.x_m, abs=1e-9)
    assert graph.final_y_m == pytest.approx(twin.final_state.y_m, abs=1e-9)
    assert graph.deviation_m < TOLERANCE_M
    said = {name: int(graph.status[name]) for name in ('stops', 'replans', 'captures_in_motion')}
    assert said == {'stops': twin.stops, 'replans': twin.replans,
                    'captures_in_motion': twin.captures_in_motion}
    assert said['replans'] > 20


def test_same_seed_same_bag_at_another_speed_busy_and_in_one_process(reference, tmp_path,
                                                                      busy_machine):
    with busy_machine():
        bag, result = servo_run(tmp_path / 'slow', real_time_factor=5.0)
    assert result.sim_time_s == reference[1].sim_time_s
    assert bag_digest(bag) == bag_digest(reference[0])
    composed, _ = servo_run(tmp_path / 'composed', composed=True)
    assert bag_digest(composed) == bag_digest(reference[0])


def test_on_the_rendered_images_the_servo_reaches_and_records_the_same_bag_at_any_speed(
        tmp_path, busy_machine):
    """--vision images: the tracker's captures in motion, one per frame from the finest camera
    that follows the robot, drive the same servo; the same bag as fast as the lockstep allows
    with the loop in one process, and at rtf 2 in separate processes with both cores busy."""
    fast_bag, fast = servo_run(tmp_path / 'fast', vision='images', composed=True)
    assert fast.outcome == 'reached' and fast.deviation_m < TOLERANCE_M
    assert int(fast.status['replans']) > 20 and fast.sim_time_s < 9.0
    with busy_machine():
        slow_bag, slow = servo_run(tmp_path / 'slow', real_time_factor=2.0, vision='images')
    assert slow.sim_time_s == fast.sim_time_s
    assert bag_digest(slow_bag) == bag_digest(fast_bag)


def test_the_servo_s_bag_replayed_into_a_fresh_camera_gives_its_captures_in_motion(
        reference, start_node, probe, domain_id):
    """The recorded /odom replayed into a fresh vision_node of the same seed yields every
    capture in motion the servo acted on, stamp and pose (the camera is a function of both)."""
    from geometry_msgs.msg import PoseWithCovarianceStamped
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    bag, _ = reference
    start_node('omni_micro_vision', 'vision_node', f'seed:={SEED}', 'captures_in_motion:=true')
    captures: list[PoseWithCovarianceStamped] = []
    readers = [probe.node.create_subscription(
        PoseWithCovarianceStamped, topic, captures.append,
        QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        for topic in CAPTURE_IN_MOTION_TOPICS.values()]
    probe.spin_until(lambda: all(r.get_publisher_count() > 0 for r in readers), 60.0,
                     "the probe matched to the vision_node's writers of captures in motion")
    replay = subprocess.Popen(
        [str(ROOT / 'scripts' / 'omni-micro'), 'replay', str(bag), '--topics', ODOM_TOPIC,
         '--rate', '10', '--wait-subscribers', '30', '--sync', 'vision_node',
         '--domain-id', str(domain_id)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    probe.spin_until(lambda: replay.poll() is not None, 240.0, 'the replay to finish')
    assert replay.returncode == 0, replay.communicate()[0]
    probe.spin_for(2.0)
    recorded = read_bag(bag, list(CAPTURE_IN_MOTION_TOPICS.values()))

    def key(msg: PoseWithCovarianceStamped) -> tuple[int, float, float]:
        return stamp_ns(msg.header.stamp), msg.pose.pose.position.x, msg.pose.pose.position.y

    expected = sorted(key(m) for topic in recorded.messages for m in recorded.messages[topic])
    assert len(expected) > 200
    assert sorted(key(m) for m in captures) == expected
