"""`omni-micro track` on a driver's recorded frames. With ``--robots``: before a bench run of
several robots, the frames of the shared camera say who the tracker names, how often each is
still, and which robot it could not name and why; a robot never named fails the command. Of one
robot: a spread over still frames only where two come in a row."""

from __future__ import annotations

import csv
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np

from omni_micro_sim.state import RobotState
from omni_micro_tools.bags import open_writer
from omni_micro_tools.topics import driver_image_topics
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.image_messages import ImageWriter
from omni_micro_vision.rendering import InView, Sensor, render_robots

ROOT = Path(__file__).resolve().parents[2]
TOPIC = '/bench/camera/image_raw'


def omni_micro(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'omni_micro_cli', *args], cwd=ROOT,
                          capture_output=True, text=True)


def recorded(bag: Path, robots: list[InView] | Callable[[int], list[InView]],
             frames: int) -> Path:
    """A driver's mono8 frames of ``robots`` (or, a function, of frame k's) under the macro
    camera, 30 Hz, in a bag."""
    writer, connections = open_writer(bag, 'mcap', driver_image_topics([TOPIC]))
    images = ImageWriter('bench_camera', 1024, 1280, 'mono8')
    try:
        for index in range(frames):
            pixels = render_robots(DEFAULT_RIG.macro, Sensor(),
                                   robots(index) if callable(robots) else robots,
                                   np.random.default_rng([2, index]))
            stamp_ns = 1_700_000_000_000_000_000 + index * 33_333_333
            writer.write(connections[TOPIC], stamp_ns,
                         images.image(*divmod(stamp_ns, 1_000_000_000), pixels))
    finally:
        writer.close()
    return bag


def test_each_robot_named_and_still_and_the_one_without_a_code_said(tmp_path):
    bag = recorded(tmp_path / 'shared', [
        InView(RobotState(0.02, 0.03, 0.5), 0), InView(RobotState(0.08, -0.02, -2.0), 2),
        InView(RobotState(0.05, 0.05, 1.0))], frames=4)
    rows = tmp_path / 'rows.csv'
    done = omni_micro('track', str(bag), '--camera', 'macro', '--image-topic', TOPIC,
                      '--robots', 'robot_0,robot_2', '--csv', str(rows))
    assert done.returncode == 0, done.stderr
    lines = done.stdout.splitlines()
    assert lines[:4] == [
        'macro camera, 4 frames, robots robot_0, robot_2:',
        '  robot_0: named in 4 frames, still (a capture) in 2',
        '  robot_2: named in 4 frames, still (a capture) in 2',
        "      4 x a robot not named: cannot tell apart: its code 00000 is no robot's"]
    table = list(csv.DictReader(rows.open()))
    assert len(table) == 12
    first = next(row for row in table if row['robot'] == 'robot_2')
    assert abs(float(first['x_m']) - 0.08) < 30e-6 and abs(float(first['y_m']) + 0.02) < 30e-6


def test_a_robot_never_named_fails_saying_which(tmp_path):
    bag = recorded(tmp_path / 'one', [InView(RobotState(0.02, 0.03, 0.5), 0)], frames=2)
    done = omni_micro('track', str(bag), '--camera', 'macro', '--image-topic', TOPIC,
                      '--robots', 'robot_0,robot_4')
    assert done.returncode == 1
    assert done.stderr.strip() == ('never named: robot_4 (check that each carries its code and '
                                   'stands whole in the field)')
    bad = omni_micro('track', str(bag), '--robots', 'robot_0,gripper')
    assert bad.returncode == 2
    assert "'gripper' is not a robot with a code of its own (robot_0 to robot_9" in bad.stderr


def test_still_frames_never_two_in_a_row_say_the_spread_was_not_measured(tmp_path):
    """A robot nudged 1 mm every third frame is still (three frames agree) on each third frame
    alone: no stretch to scatter about, so no spread and no advice, said in one line (it was a
    traceback)."""
    bag = recorded(tmp_path / 'nudged',
                   lambda index: [InView(RobotState(0.05 + 1e-3 * (index // 3), 0.01, 0.3))],
                   frames=9)
    done = omni_micro('track', str(bag), '--camera', 'macro', '--image-topic', TOPIC)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [
        'macro camera, 9 frames: fiducial found in 9, still (a capture) in 3',
        'spread over still frames: not measured, no two still frames come in a row']
