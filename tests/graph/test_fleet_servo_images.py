"""Servos on the shared cameras (`run --robots FILE --vision images`, every robot a servo): the
one tracker names each robot in every frame, still or moving, and gives each its own captures in
motion under its namespace, from the finest camera that follows it (one robot drives into the
micro camera's field). Three servo robots reach their goals, every capture in motion lies within
150 um of its own robot and far from the others, and the same seed records the same bag at
another speed, composed (docs/fleet.md, "Servos on the shared cameras")."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from fleet_runs import assert_same_run_and_bag, run_fleet_files

from omni_micro_tools.bag_reading import read_bag

ROBOTS = """robots:
  - start_mm: [30, 0]
    wheel_offsets_deg: [0, 3, 2]
    controller: servo
  - start_mm: [55, 0]
    wheel_offsets_deg: [0, -2, 1]
    controller: servo
  - start_mm: [85, 0]
    wheel_offsets_deg: [0, 2, -3]
    controller: servo
"""
TASKS = """tasks:
  robot_0:
    - goal_mm: [30, 12]
  robot_1:
    - goal_mm: [55, -12]
  robot_2:
    - goal_mm: [100, 0]
"""
GOALS_MM = [(30.0, 12.0), (55.0, -12.0), (100.0, 0.0)]
COUNT = len(GOALS_MM)
CAMERAS = ('macro', 'micro')


def servos_on_images(omni_micro, folder: Path, *extra: str) -> dict:
    return run_fleet_files(omni_micro, folder, ROBOTS, TASKS, '--vision', 'images', '--seed',
                           '2', '--no-markers', *extra)


@pytest.fixture(scope='module')
def on_images(omni_micro, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp('fleet_servo_images')
    summary = servos_on_images(omni_micro, folder)
    (folder / 'summary.json').write_text(json.dumps(summary))
    return folder


def stamp_s(message) -> float:
    return message.header.stamp.sec + message.header.stamp.nanosec * 1e-9


def test_three_servos_on_the_shared_cameras_reach_their_goals(on_images):
    summary = json.loads((on_images / 'summary.json').read_text())
    assert summary['outcome'] == 'done', summary['reason']
    assert summary['closest_gap_mm'] > 9.0
    for robot, goal in zip(summary['robots'], GOALS_MM, strict=True):
        assert robot['goals_reached'] == 1 and robot['outcome'] == 'done'
        assert math.dist(robot['final_mm'], goal) < 0.05
    (logs,) = (on_images / 'logs').iterdir()
    assert 'not named' not in (logs / 'tracker_node.log').read_text()


def test_every_capture_in_motion_is_of_its_own_robot(on_images):
    """Robot k's captures in motion lie within 150 um of where its odometry has it at their
    stamp (an exposure's middle, between two samples: interpolated), never near another robot;
    the robot driven into the micro field has them from the micro camera there."""
    topics = [f'/robot_{k}/{kind}' for k in range(COUNT)
              for kind in ('odom', *(f'camera/{name}/pose_in_motion' for name in CAMERAS))]
    bag = read_bag(on_images / 'bag', topics=topics)
    tracks = {}
    for k in range(COUNT):
        odometry = bag.messages[f'/robot_{k}/odom']
        tracks[k] = (np.array([stamp_s(m) for m in odometry]),
                     np.array([(m.pose.pose.position.x, m.pose.pose.position.y)
                               for m in odometry]))

    def where(robot: int, stamp: float) -> tuple[float, float]:
        stamps, xy = tracks[robot]
        assert stamps[0] <= stamp <= stamps[-1]
        return float(np.interp(stamp, stamps, xy[:, 0])), float(np.interp(stamp, stamps, xy[:, 1]))

    for k in range(COUNT):
        by_camera = {name: bag.messages[f'/robot_{k}/camera/{name}/pose_in_motion']
                     for name in CAMERAS}
        assert len(by_camera['macro']) > 20, k
        for capture in (m for messages in by_camera.values() for m in messages):
            seen = (capture.pose.pose.position.x, capture.pose.pose.position.y)
            stamp = stamp_s(capture)
            assert math.dist(seen, where(k, stamp)) < 150e-6, (k, stamp)
            for other in set(range(COUNT)) - {k}:
                assert math.dist(seen, where(other, stamp)) > 5e-3
    assert len(bag.messages['/robot_2/camera/micro/pose_in_motion']) > 0
    assert not bag.messages['/robot_0/camera/micro/pose_in_motion']


def test_the_same_run_and_bag_composed_at_twice_real_time(on_images, omni_micro, tmp_path):
    """The same JSON but its wall times, and the same bag file, byte for byte."""
    paced = servos_on_images(omni_micro, tmp_path, '--rtf', '2', '--composed')
    assert_same_run_and_bag(on_images, tmp_path, paced)
