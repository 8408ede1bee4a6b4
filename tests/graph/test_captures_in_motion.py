"""Captures of the moving robot through the graph (`run --captures-in-motion`): vision_node, or
tracker_node on rendered frames, publishes them on /camera/<name>/pose_in_motion, each stamped
at the middle of a frame's exposure and within its stated uncertainty of where /odom puts the
robot then, none while the robot stands; the stationary captures and the run are what they are
without them."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from conftest import SHARED_SEED

from omni_micro_common.conventions import CaptureUncertainty, stamp_ns
from omni_micro_common.topic_names import (
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    ODOM_TOPIC,
)
from omni_micro_tools.bag_reading import read_bag

FRAME_NS = 1_000_000_000 / 30.0
HALF_EXPOSURE_NS = 2_000_000


@pytest.fixture(scope='module')
def runs(tmp_path_factory, omni_micro, fig11_recorded):
    """The shared Fig. 11 run, and the same with captures in motion (in one process: the loop
    composed records what separate processes do, tests/graph/test_same_bag.py)."""
    folder = tmp_path_factory.mktemp('in_motion')
    result = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--seed',
                        str(SHARED_SEED), '--json', '--quiet', '--composed', '--no-markers',
                        '--record',
                        str(folder / 'moving'), '--log-dir', str(folder / 'logs'),
                        '--captures-in-motion')
    assert result.returncode == 0, result.stderr[-3000:]
    plain_bag, plain = fig11_recorded
    bags = {'moving': folder / 'moving', 'plain': plain_bag}
    return bags, {'moving': json.loads(result.stdout.strip().splitlines()[-1]), 'plain': plain}


def odometry_at(stamps: np.ndarray, odometry: list) -> tuple[np.ndarray, np.ndarray]:
    """Where /odom puts the robot at ``stamps`` (ns), linear between samples, and its speed."""
    times = np.array([stamp_ns(msg.header.stamp) for msg in odometry], dtype=float)
    xs = np.array([msg.pose.pose.position.x for msg in odometry])
    ys = np.array([msg.pose.pose.position.y for msg in odometry])
    speeds = np.array([math.hypot(msg.twist.twist.linear.x, msg.twist.twist.linear.y)
                       for msg in odometry])
    return (np.stack([np.interp(stamps, times, xs), np.interp(stamps, times, ys)], axis=1),
            np.interp(stamps, times, speeds))


def test_captures_in_motion_are_at_mid_exposure_within_their_stated_spread(runs):
    bags, _ = runs
    bag = read_bag(bags['moving'], [ODOM_TOPIC, *CAPTURE_IN_MOTION_TOPICS.values()])
    seen = {camera: bag.messages.get(topic, []) for camera, topic in
            CAPTURE_IN_MOTION_TOPICS.items()}
    # Fig. 11 rolls 7 s at up to cruise speed: some 200 macro frames.
    assert len(seen['macro']) > 150
    for camera, captures in seen.items():
        if not captures:
            continue
        stamps = np.array([stamp_ns(msg.header.stamp) for msg in captures], dtype=float)
        frames = (stamps - HALF_EXPOSURE_NS) / FRAME_NS
        assert np.allclose(frames, np.round(frames), atol=1e-6), camera
        truth, speeds = odometry_at(stamps, bag.messages[ODOM_TOPIC])
        assert np.all(speeds > 1e-6), camera
        for msg, (x, y) in zip(captures, truth, strict=True):
            stated = CaptureUncertainty.from_covariance(msg.pose.covariance)
            assert abs(msg.pose.pose.position.x - x) < 5 * stated.x_sigma_m, camera
            assert abs(msg.pose.pose.position.y - y) < 5 * stated.y_sigma_m, camera


def test_the_stationary_captures_and_the_run_are_the_same_with_them(runs):
    bags, summaries = runs
    moving, plain = summaries['moving'], summaries['plain']
    for key in ('outcome', 'periods', 'sim_time_s', 'final_x_mm', 'final_y_mm'):
        assert moving[key] == plain[key], key
    topics = list(CAPTURE_TOPICS.values())
    with_them, without = read_bag(bags['moving'], topics), read_bag(bags['plain'], topics)
    for topic in topics:
        assert with_them.raw.get(topic) == without.raw.get(topic), topic
    assert not set(CAPTURE_IN_MOTION_TOPICS.values()) & set(without.msgtypes)


def test_the_tracker_captures_the_rendered_robot_in_motion_at_mid_exposure(omni_micro,
                                                                            tmp_path):
    """--vision images: tracker_node turns each frame it finds moving into a capture stamped
    half camera_node's exposure after the frame, within its stated spread of /odom."""
    bag = tmp_path / 'bag'
    result = omni_micro('run', '--goal-mm', '100,0', '--vision', 'images', '--rtf', 'max',
                        '--captures-in-motion', '--quiet', '--composed', '--no-markers',
                        '--record', str(bag),
                        '--log-dir', str(tmp_path / 'logs'))
    assert result.returncode == 0, result.stderr[-3000:]
    read = read_bag(bag, [ODOM_TOPIC, *CAPTURE_IN_MOTION_TOPICS.values()])
    captures = read.messages.get(CAPTURE_IN_MOTION_TOPICS['macro'], [])
    assert len(captures) > 150
    stamps = np.array([stamp_ns(msg.header.stamp) for msg in captures], dtype=float)
    frames = (stamps - HALF_EXPOSURE_NS) / FRAME_NS
    assert np.allclose(frames, np.round(frames), atol=1e-6)
    # Moving is the tracker's stillness rule on the images: a frame just after a stop, its
    # robot at rest, still differs from the frames before it (and is then as good a capture).
    truth, _ = odometry_at(stamps, read.messages[ODOM_TOPIC])
    for msg, (x, y) in zip(captures, truth, strict=True):
        stated = CaptureUncertainty.from_covariance(msg.pose.covariance)
        assert abs(msg.pose.pose.position.x - x) < 5 * stated.x_sigma_m
        assert abs(msg.pose.pose.position.y - y) < 5 * stated.y_sigma_m


def test_a_graph_without_a_camera_node_to_publish_them_is_refused():
    from omni_micro_bringup.composition import all_specs
    from omni_micro_bringup.errors import UsageError
    from omni_micro_bringup.graph_options import GraphOptions
    from omni_micro_bringup.node_spec import NodeSpec

    robot_and_controller = [NodeSpec('omni_micro_sim', 'dynamics_node'),
                            NodeSpec('omni_micro_control', 'controller_node')]
    with pytest.raises(UsageError, match='vision_node or tracker_node publishes captures in '
                                         'motion, and this graph has neither'):
        all_specs(GraphOptions(goal_m=(0.1, 0.0), nodes=robot_and_controller,
                               captures_in_motion=True))


def test_same_seed_same_bag_with_late_captures_in_motion_at_another_speed(tmp_path):
    """With a camera 50 ms late and up to 20 ms of jitter, the recorded bag is the same file
    at --rtf max and at --rtf 5: the delay is simulated time, not message latency."""
    from bag_compare import bag_digest

    from omni_micro_bringup.graph import run_graph
    from omni_micro_bringup.graph_options import GraphOptions

    late: dict[str, object] = {'macro.motion.delay_s': 0.05, 'macro.motion.jitter_s': 0.02,
                               'micro.motion.delay_s': 0.05, 'micro.motion.jitter_s': 0.02}
    digests = []
    for name, rtf in (('fast', math.inf), ('slow', 5.0)):
        folder = tmp_path / name
        result = run_graph(GraphOptions(goal_m=(0.1, 0.0), seed=3, real_time_factor=rtf,
                                        record=folder / 'bag', log_dir=folder / 'logs',
                                        captures_in_motion=True, vision_overrides=late))
        assert result.outcome == 'reached', result.reason
        in_motion = read_bag(folder / 'bag', [CAPTURE_IN_MOTION_TOPICS['macro']])
        assert len(in_motion.raw[CAPTURE_IN_MOTION_TOPICS['macro']]) > 150
        digests.append(bag_digest(folder / 'bag'))
    assert digests[0] == digests[1]
