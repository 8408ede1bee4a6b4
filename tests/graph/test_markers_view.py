"""Markers and the live view: /markers draws the state it was given, a WebSocket client that is
not ours decodes the live view with the advertised schemas, and neither changes the run."""

import asyncio
import json
import math
import os
import shutil
import signal
import socket
import subprocess
from pathlib import Path

import pytest
from conftest import SHARED_SEED
from foxglove_client import free_port, wait_for_view, watch

from omni_micro_common.conventions import quaternion_to_yaw
from omni_micro_tools.bag_reading import read_bag
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.scene import RobotGeometry

ROOT = Path(__file__).resolve().parents[2]
GOAL = (0.1, 0.0)
# Every decision of the run. (After the outcome the graph runs on for a few ticks until it is
# stopped, as many as wall time allows: /odom is compared up to the last capture.)
COMPARED_TOPICS = ('/camera/macro/pose', '/camera/micro/pose', '/wheel_trajectory',
                   '/controller/status')


def _run(omni_micro, folder: Path, *extra: str):
    bag = folder / 'bag'
    result = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--seed', str(SHARED_SEED),
                        '--json', '--quiet', '--record', str(bag), '--log-dir',
                        str(folder / 'logs'), *extra)
    assert result.returncode == 0, result.stderr[-3000:]
    return bag, json.loads(result.stdout.strip().splitlines()[-1])


@pytest.fixture(scope='module')
def with_markers(fig11_recorded):
    """The shared Fig. 11 run (seed 3, with markers: the default)."""
    return fig11_recorded


def test_markers_draw_the_odometry_goal_and_fields_they_were_given(with_markers):
    bag, summary = with_markers
    messages = read_bag(bag, ['/markers', '/odom'])
    odometry = {(m.header.stamp.sec, m.header.stamp.nanosec): m.pose.pose
                for m in messages.messages['/odom']}
    arrays = messages.messages['/markers']
    assert len(arrays) >= len(odometry) // 5 - 2     # one per 0.1 s (5 samples), as configured
    geometry = RobotGeometry()
    drawn = goals_drawn = fields_drawn = 0
    for array in arrays:
        by_name = {(marker.ns, marker.id): marker for marker in array.markers}
        for marker in array.markers:
            assert marker.header.frame_id == 'platform'
        chassis = by_name[('robot/chassis', 0)]
        pose = odometry[(chassis.header.stamp.sec, chassis.header.stamp.nanosec)]
        assert (chassis.pose.position.x, chassis.pose.position.y) == \
            (pose.position.x, pose.position.y)
        phi = quaternion_to_yaw(pose.orientation.z, pose.orientation.w)
        wheel_1 = by_name[('robot/wheel_1', 0)].points[0]
        expected = geometry.wheel_contacts(pose.position.x, pose.position.y, phi)[0]
        assert math.dist((wheel_1.x, wheel_1.y), expected) < 1e-12
        assert chassis.scale.x == pytest.approx(9e-3)     # the 9 mm chassis
        drawn += 1
        if ('goal', 0) in by_name:
            goal = by_name[('goal', 0)].points[0]
            assert (goal.x, goal.y) == GOAL
            goals_drawn += 1
        fields = {marker.id: [(p.x, p.y) for p in marker.points]
                  for marker in array.markers if marker.ns == 'fields'}
        if fields:
            fields_drawn += 1
            for index, camera in enumerate((DEFAULT_RIG.macro, DEFAULT_RIG.micro)):
                xs = [x for x, _ in fields[index]]
                ys = [y for _, y in fields[index]]
                assert (min(xs) + max(xs)) / 2 == pytest.approx(camera.center_m[0])
                assert max(xs) - min(xs) == pytest.approx(camera.field_m[0])
                assert max(ys) - min(ys) == pytest.approx(camera.field_m[1])
    assert drawn == len(arrays)
    assert goals_drawn >= 1 and fields_drawn >= len(odometry) // 250 - 1   # refreshed each 5 s
    last = {(marker.ns, marker.id): marker for marker in arrays[-1].markers}
    final = last[('robot/chassis', 0)].pose.position
    assert math.hypot(final.x - summary['final_x_mm'] * 1e-3,
                      final.y - summary['final_y_mm'] * 1e-3) < 1e-9


def test_the_run_is_the_same_without_markers(with_markers, omni_micro, tmp_path):
    bag, summary = with_markers
    bare_bag, bare = _run(omni_micro, tmp_path, '--no-markers')
    assert '/markers' not in read_bag(bare_bag).msgtypes
    assert_same_run(bag, summary, bare_bag, bare)


def assert_same_run(bag: Path, summary: dict, other_bag: Path, other: dict) -> None:
    """The same outcome, and the same messages on every topic up to it, markers included where
    both runs drew them. (After the outcome the graph runs on until it is stopped, as long as
    wall time makes it: more captures and odometry, and the stop sent at shutdown.)"""
    for key in ('outcome', 'periods', 'sim_time_s'):
        assert other[key] == summary[key], key
    # The summary's final pose is the first /odom sample the orchestrator reads after the
    # outcome, at a moment the wall clock decides, and the stopped robot still creeps by a
    # picometre (seen in CI); the bags' odometry up to the outcome is compared exactly below.
    for key in ('final_x_mm', 'final_y_mm'):
        assert other[key] == pytest.approx(summary[key], abs=1e-6), key    # 1 nm: at rest
    ours, theirs = read_bag(bag), read_bag(other_bag)
    outcome_ns = round(summary['sim_time_s'] * 1e9)     # the decisive capture's stamp
    drawn = ('/markers',) if '/markers' in ours.raw and '/markers' in theirs.raw else ()
    for topic in (*COMPARED_TOPICS, '/odom', *drawn):
        # Markers decoded: the serializer leaves a MarkerArray's alignment padding
        # uninitialised, so equal arrays can differ in those bytes.
        first: list = ours.raw[topic]
        second: list = theirs.raw[topic]
        if topic == '/markers':
            first = [repr(m) for m in ours.messages[topic]]
            second = [repr(m) for m in theirs.messages[topic]]
        before = [item for item, message in zip(first, ours.messages[topic], strict=True)
                  if _stamp_ns(message) <= outcome_ns]
        assert before and second[:len(before)] == before, topic


def _stamp_ns(message) -> int:
    if getattr(message, 'markers', None):      # a MarkerArray is stamped by its markers
        message = message.markers[-1]
    header = getattr(message, 'header', None)
    if header is None:           # DiagnosticStatus: in order, compared whole
        return 0
    return header.stamp.sec * 10**9 + header.stamp.nanosec


def _approached(received: dict[str, list]) -> bool:
    """The robot seen 10 mm closer to the goal than it was first seen."""
    odometry = received.get('/odom', [])
    distances = [math.dist((m.pose.pose.position.x, m.pose.pose.position.y), GOAL)
                 for m in (odometry[0], odometry[-1])] if odometry else [0.0, 0.0]
    return distances[1] < distances[0] - 0.01


def test_a_slow_foxglove_client_watches_the_robot_approach_and_changes_nothing(
        with_markers, tmp_path, omni_micro):
    """A client decodes what it gets with the advertised schemas and sees the robot come 10 mm
    closer; then it reads 5 ms per message (the graph at --rtf max sends ~1,700 a second); the
    run and its bag are those of the run without a viewer."""
    bag, summary = with_markers
    port = free_port()
    folder = tmp_path / 'viewed'
    run = subprocess.Popen(
        [str(ROOT / 'scripts' / 'omni-micro'), 'run', '--goal-mm', '100,0', '--rtf', 'max',
         '--seed', '3', '--json', '--quiet', '--record', str(folder / 'bag'), '--log-dir',
         str(folder / 'logs'), '--view', '--view-port', str(port)],
        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, env=dict(os.environ))
    try:
        wait_for_view(port, run)
        received = asyncio.run(watch(f'ws://127.0.0.1:{port}', 30.0, _approached,
                                      then_slow_s=3.0))
        stdout, stderr = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            os.killpg(run.pid, signal.SIGINT)
            run.communicate(timeout=60)
    assert run.returncode == 0, stderr[-3000:]
    assert f'live view: ws://127.0.0.1:{port}' in stderr
    assert _approached(received), f'{len(received.get("/odom", []))} odometry messages'
    assert received['/markers'] and received['/clock']
    assert_same_run(bag, summary, folder / 'bag', json.loads(stdout.strip().splitlines()[-1]))


def test_analyze_animates_the_run_from_the_bag_alone(with_markers, tmp_path, omni_micro):
    from PIL import Image

    bag, _ = with_markers
    result = omni_micro('analyze', str(bag), '--out', str(tmp_path / 'analysis'), '--animate',
                        '--frames', '12')
    assert result.returncode == 0, result.stderr[-3000:]
    assert '12/12' in result.stderr                      # the progress bar reached the end
    with Image.open(tmp_path / 'analysis' / 'run.gif') as movie:
        assert movie.size == (1000, 450)
        assert getattr(movie, 'n_frames', 1) == 12
    with Image.open(tmp_path / 'analysis' / 'run_last_frame.png') as still:
        assert still.size == (1000, 450)
    if shutil.which('ffmpeg') is None:     # an MP4 cannot be made here: said, nothing written
        failed = omni_micro('analyze', str(bag), '--out', str(tmp_path / 'mp4'), '--animate',
                            'mp4')
        assert failed.returncode == 2 and 'needs ffmpeg' in failed.stderr
        assert not (tmp_path / 'mp4').exists()


def test_a_taken_view_port_is_refused_before_the_graph_starts(omni_micro, tmp_path):
    with socket.socket() as taken:
        taken.bind(('127.0.0.1', 0))
        taken.listen()
        port = taken.getsockname()[1]
        result = omni_micro('run', '--goal-mm', '100,0', '--view', '--view-port', str(port),
                            '--log-dir', str(tmp_path / 'logs'))
    assert result.returncode == 2
    assert f'--view-port {port}: cannot listen on 127.0.0.1:{port}' in result.stderr
    assert not (tmp_path / 'logs').exists()          # no graph was started
