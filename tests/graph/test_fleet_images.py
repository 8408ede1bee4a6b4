"""A fleet on rendered images (`fleet --graph --vision images`): one camera_node renders
every robot with its code, one tracker_node names each in the frames and publishes its captures
under its namespace, each robot's lockstep gate hearing of its own captures only. Two robots
crossing each other's goals reach them clear of each other (in the model mode, the quickest to
a goal on still captures), every capture in the bag is of the robot it is published for, and
the run is the same at another speed, composed (docs/fleet.md, "Who is who")."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from fleet_runs import assert_same_run_and_bag, run_fleet_files

from omni_micro_tools.bag_reading import read_bag

ROBOTS = """robots:
  - start_mm: [40, 0]
    wheel_offsets_deg: [0, 3, 2]
    controller: model
  - start_mm: [60, 0]
    wheel_offsets_deg: [0, -2, 1]
    controller: model
"""
TASKS = """tasks:
  robot_0:
    - goal_mm: [60, 0]
  robot_1:
    - goal_mm: [40, 0]
"""
GOALS_MM = [(60.0, 0.0), (40.0, 0.0)]
CAMERAS = ('macro', 'micro')


def fleet_on_images(omni_micro, folder: Path, *extra: str) -> dict:
    return run_fleet_files(omni_micro, folder, ROBOTS, TASKS, '--vision', 'images', '--seed',
                           '3', *extra)


@pytest.fixture(scope='module')
def on_images(omni_micro, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp('fleet_images')
    summary = fleet_on_images(omni_micro, folder)
    (folder / 'summary.json').write_text(json.dumps(summary))
    return folder


def test_one_camera_and_one_tracker_tell_two_crossing_robots_apart(on_images):
    summary = json.loads((on_images / 'summary.json').read_text())
    assert summary['outcome'] == 'done', summary['reason']
    assert summary['closest_gap_mm'] > 9.0
    for robot, goal in zip(summary['robots'], GOALS_MM, strict=True):
        assert robot['goals_reached'] == 1 and robot['outcome'] == 'done'
        assert robot['deviation_um'][0] < 50.0   # the macro camera's, outside the micro field
        assert math.dist(robot['final_mm'], goal) < 0.05
    # The shared cameras in place of each robot's vision_node.
    (logs,) = (on_images / 'logs').iterdir()
    names = sorted(path.name for path in logs.glob('*.log'))
    assert 'camera_node.log' in names and 'tracker_node.log' in names
    assert not [name for name in names if 'vision_node' in name]
    assert 'not named' not in (logs / 'tracker_node.log').read_text()


def test_every_capture_is_of_the_robot_it_is_published_for(on_images):
    """Each robot's captures lie where that robot's odometry has it at their stamp (the
    tracker's pixel error), never where the other robot is: the robots stay 11 mm apart."""
    topics = [f'/robot_{k}/{kind}' for k in range(2)
              for kind in ('odom', *(f'camera/{name}/pose' for name in CAMERAS))]
    bag = read_bag(on_images / 'bag', topics=topics)
    poses = {}
    for k in range(2):
        odometry = bag.messages[f'/robot_{k}/odom']
        poses[k] = (np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
                              for m in odometry]),
                    np.array([(m.pose.pose.position.x, m.pose.pose.position.y)
                              for m in odometry]))
    for k in range(2):
        captures = [m for name in CAMERAS for m in bag.messages[f'/robot_{k}/camera/{name}/pose']]
        assert len(captures) > 20
        for capture in captures:
            stamp = capture.header.stamp.sec + capture.header.stamp.nanosec * 1e-9
            seen = (capture.pose.position.x, capture.pose.position.y)
            distances = {}
            for robot, (stamps, xy) in poses.items():
                index = int(np.argmin(np.abs(stamps - stamp)))
                # A still robot is captured: the odometry at its stamp is where it stands.
                assert abs(stamps[index] - stamp) < 0.02
                distances[robot] = math.dist(seen, xy[index])
            assert distances[k] < 100e-6, (k, stamp, distances)
            assert distances[1 - k] > 5e-3


def test_the_same_run_and_bag_composed_at_twice_real_time(on_images, omni_micro, tmp_path):
    """The same JSON but its wall times, and the same bag file, byte for byte."""
    paced = fleet_on_images(omni_micro, tmp_path, '--rtf', '2', '--composed')
    assert_same_run_and_bag(on_images, tmp_path, paced)


def test_the_shared_cameras_images_recorded_name_each_robot_offline(omni_micro, tmp_path):
    """``run --robots --vision images --record-images``: the bag keeps every frame of both
    shared cameras, and ``track`` reading them afterwards names both robots in every macro frame
    and finds each still as often as the live tracker published its captures."""
    (tmp_path / 'robots.yaml').write_text(ROBOTS)
    # Short moves (3 mm each, apart): the frames are 2 x 3.9 MB at 30 Hz.
    (tmp_path / 'tasks.yaml').write_text('tasks:\n  robot_0:\n    - goal_mm: [37, 0]\n'
                                         '  robot_1:\n    - goal_mm: [63, 0]\n')
    done = omni_micro('run', '--robots', str(tmp_path / 'robots.yaml'), '--tasks',
                      str(tmp_path / 'tasks.yaml'), '--vision', 'images', '--seed', '3',
                      '--no-markers', '--rtf', 'max', '--log-dir', str(tmp_path / 'logs'),
                      '--record', str(tmp_path / 'bag'), '--record-images', '--quiet')
    assert done.returncode == 0, done.stderr[-3000:]
    topics = [f'/camera/{camera}/{stream}' for camera in CAMERAS
              for stream in ('image_raw', 'camera_info')]
    captures = [f'/robot_{k}/camera/macro/pose' for k in range(2)]
    bag = read_bag(tmp_path / 'bag', topics=[*topics, *captures])
    frames = {len(bag.messages[topic]) for topic in topics}
    assert len(frames) == 1 and frames.pop() > 30    # every frame, with its camera info
    tracked = omni_micro('track', str(tmp_path / 'bag'), '--camera', 'macro', '--robots',
                         'robot_0,robot_1')
    assert tracked.returncode == 0, tracked.stderr[-2000:]
    count = len(bag.messages['/camera/macro/image_raw'])
    for k, topic in enumerate(captures):
        assert (f'robot_{k}: named in {count} frames, still (a capture) in '
                f'{len(bag.messages[topic])}') in tracked.stdout, tracked.stdout
