"""`omni-micro fleet` as a user runs it: robots and tasks from files, the table, the JSON, the
routes' figure; every bad value of a file named in one line, nothing written."""

from __future__ import annotations

import itertools
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from omni_micro_cli.cli import build_parser
from omni_micro_cli.graph_arguments import composition_of
from omni_micro_common.conventions import STATUS_TIME_KEY
from omni_micro_control.fleet_roadmap import CLEARANCE_M, ROBOT_DIAMETER_M

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]

ROBOTS = """robots:
  - start_mm: [0, 0]
    wheel_offsets_deg: [0, 3, 2]
  - start_mm: [100, 0]
"""
TASKS = """tasks:
  robot_0:
    - goal_mm: [100, 0.2]
    - goal_mm: [40, 40]
  robot_1:
    - goal_mm: [0, 0]
      after: [0, 0]
"""


def omni_micro(*args, cwd=ROOT):
    return subprocess.run([sys.executable, '-m', 'omni_micro_cli', *args], cwd=cwd,
                          capture_output=True, text=True, timeout=300)


def test_a_fleet_from_files_reaches_every_goal_in_order_and_is_drawn(tmp_path):
    (tmp_path / 'robots.yaml').write_text(ROBOTS)
    (tmp_path / 'tasks.yaml').write_text(TASKS)
    plot = tmp_path / 'routes.png'
    done = omni_micro('fleet', '--robots', str(tmp_path / 'robots.yaml'), '--tasks',
                      str(tmp_path / 'tasks.yaml'), '--seed', '2', '--plot', str(plot),
                      '--json')
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    assert summary['outcome'] == 'done' and summary['goals_reached'] == 3
    first, second = summary['robots']
    assert first['wheel_offsets_deg'] == [0, 3, 2]
    # Robot 1 swaps places with robot 0, entering robot 0's start only after robot 0 has
    # reached the micro field.
    assert second['reached_at_s'][0] > first['reached_at_s'][0]
    assert first['deviation_um'][0] <= 3.0 and second['deviation_um'][0] <= 50.0
    assert summary['closest_gap_mm'] > 9.0
    assert '2/2' in done.stderr and 'planned 2 robots' in done.stderr
    assert '3/3 goals reached at' in done.stderr
    assert plot.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'


@pytest.mark.parametrize('robots, tasks, message', [
    ('0', None, "--robots must be a whole number 1..42 or a YAML file, got '0'"),
    ('ROBOTS', 'tasks:\n  robot_5:\n    - goal_mm: [1, 2]\n',
     "names ['robot_5']: the robots are robot_0..robot_1"),
    ('ROBOTS', 'tasks:\n  robot_0:\n    - goal_mm: [300, 0]\n',
     "robot 0's goal 0 (300, 0) mm is off the platform"),
    ('ROBOTS', 'tasks:\n  robot_0:\n    - goal_mm: [nan, 0]\n',
     'goal_mm must be two finite numbers [x, y], got'),
    ('ROBOTS', 'tasks:\n  robot_0:\n    - goal_mm: [10, 0]\n      after: [0]\n',
     'after must be [robot, goal index], got [0]'),
    ('ROBOTS', 'tasks: [1, 2\n', 'is not YAML'),
    ('robots:\n  - start_mm: [0, 0]\n  - start_mm: [5, 0]\n', None,
     'robots 0 and 1 start 5.00 mm apart'),
    ('robots:\n  - start_mm: [0, 0]\n    controller: pid\n', None,
     "robots[0].controller must be one of paper, model, servo, open-loop, got 'pid'"),
    ('2 --goals-per-robot 3', 'tasks:\n  robot_0:\n    - goal_mm: [10, 0]\n',
     '--goals-per-robot is how many goals to draw: not with --tasks'),
])
def test_a_bad_value_is_named_in_one_line_and_nothing_is_written(tmp_path, robots, tasks,
                                                                message):
    arguments = ['fleet', '--plot', str(tmp_path / 'routes.png')]
    if robots == 'ROBOTS' or robots.startswith('robots:'):
        (tmp_path / 'robots.yaml').write_text(ROBOTS if robots == 'ROBOTS' else robots)
        arguments += ['--robots', str(tmp_path / 'robots.yaml')]
    else:
        arguments += ['--robots', *robots.split()]
    if tasks is not None:
        (tmp_path / 'tasks.yaml').write_text(tasks)
        arguments += ['--tasks', str(tmp_path / 'tasks.yaml')]
    done = omni_micro(*arguments)
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], done.stderr
    assert not (tmp_path / 'routes.png').exists()


def test_a_graph_run_refuses_to_record_over_a_bag_before_anything_starts(tmp_path):
    (tmp_path / 'bag').mkdir()
    done = omni_micro('run', '--robots', '2', '--record', str(tmp_path / 'bag'), '--log-dir',
                      str(tmp_path / 'logs'))
    assert done.returncode == 2
    assert done.stderr.strip() == (f"omni-micro run: error: '{tmp_path / 'bag'}' exists "
                                   'already; give --force to replace it')
    assert not (tmp_path / 'logs').exists()


def test_the_study_sweeps_robot_counts_and_counts_crossings(tmp_path):
    sweep = omni_micro('fleet-study', '--out', str(tmp_path / 'sweep'), '--robots-max', '2',
                       '--draws', '1', '--goals-per-robot', '1', '--workers', '2')
    assert sweep.returncode == 0, sweep.stderr
    summary = json.loads((tmp_path / 'sweep' / 'summary.json').read_text())
    assert [e['robots'] for e in summary['per_robot_count']] == [1, 2]
    # One robot has nobody to come close to: null, not a number (nor JSON's forbidden Infinity).
    assert summary['per_robot_count'][0]['closest_gap_mm'] is None
    assert summary['per_robot_count'][1]['closest_gap_mm'] > 9.0
    assert all(e['done'] == 1 for e in summary['per_robot_count'])
    assert summary['contacts'] == 0
    rows = (tmp_path / 'sweep' / 'runs.csv').read_text().splitlines()
    assert rows[0].startswith('robots,controller,seed,outcome,goals') and len(rows) == 3
    assert rows[1].startswith('1,paper,0,done,1,') and ',,' in rows[1]
    assert (tmp_path / 'sweep' / 'throughput.png').read_bytes()[:4] == b'\x89PNG'
    # Said as each run ends, in whatever order the cluster's workers finish them.
    assert re.search(r'\[[12]/2\] 2 robots, paper, seed 0: done', sweep.stderr), sweep.stderr
    crossing = omni_micro('fleet-study', '--out', str(tmp_path / 'crossing'), '--crossing', '2',
                          '--workers', '1', '--seed', '5', '--controller', 'servo')
    assert crossing.returncode == 0, crossing.stderr
    assert crossing.stdout.startswith(
        '2 crossing runs of 4 robots (servo controllers): 2 done, 0 contacts')
    result = json.loads((tmp_path / 'crossing' / 'summary.json').read_text())
    assert result['closest_gap_mm'] > 9.0 and result['runs'] == 2
    assert result['controller'] == 'servo'
    (tmp_path / 'a_file').write_text('')
    refused = omni_micro('fleet-study', '--out', str(tmp_path / 'a_file'), '--crossing', '2')
    assert refused.returncode == 2 and 'exists and is a file' in refused.stderr
    assert refused.stderr.count('\n') == 1


def test_the_crossing_puts_robots_in_opposite_pairs_on_one_circle():
    """Four make the cross of the platform (100 mm end to end); up to 24 stand 12 mm apart or
    more, each sent through the centre to the opposite point."""
    from omni_micro_studies.fleet_throughput import CROSSING_CENTRE_M, crossing_places

    assert crossing_places(4) == ([(0.0, 0.0), (0.1, 0.0), (0.05, 0.05), (0.05, -0.05)],
                                  [(0.1, 0.0), (0.0, 0.0), (0.05, -0.05), (0.05, 0.05)])
    for count in (2, 8, 16, 24):
        starts, goals = crossing_places(count)
        assert len(set(starts)) == count and sorted(goals) == sorted(starts)
        assert min(math.dist(a, b) for a, b in itertools.combinations(starts, 2)) >= 0.012
        for start, goal in zip(starts, goals, strict=True):
            middle = ((start[0] + goal[0]) / 2, (start[1] + goal[1]) / 2)
            assert math.dist(middle, CROSSING_CENTRE_M) < 1e-9
    with pytest.raises(ValueError, match='a crossing of 5 robots: expected an even count'):
        crossing_places(5)


@pytest.mark.parametrize(('arguments', 'said'), [
    (['--crossing', '1', '--crossing-robots', '7'], "--crossing-robots: expected an even count"),
    (['--crossing', '1', '--crossing-robots', '26'], 'expected a whole number in [2, 24]'),
    (['--robot-counts', '4,4'], "--robot-counts: expected each number once, got '4,4'"),
    (['--robot-counts', '8,43'], "expected a whole number in [1, 42], got '43'"),
    (['--robot-counts', '8', '--robots-max', '3'], 'not allowed with argument'),
    (['--controller', 'paper,fast'], "expected controller modes among paper, model, servo, "
                                     "open-loop, got 'fast'"),
    (['--controller', 'servo,model,servo'], "expected each controller once, got "
                                            "'servo,model,servo'"),
])
def test_study_sizes_it_cannot_run_are_refused_in_one_line(tmp_path, arguments, said):
    refused = omni_micro('fleet-study', '--out', str(tmp_path / 'out'), *arguments)
    assert refused.returncode == 2 and said in refused.stderr, refused.stderr
    assert refused.stderr.count('\n') == 1 and not (tmp_path / 'out').exists()


def test_the_study_compares_controllers_on_the_same_task_sets(tmp_path):
    """Several controllers: each runs the same task sets (same robot counts, same seeds), each
    has its summary and its line of the table, and one figure holds them all."""
    compared = omni_micro('fleet-study', '--out', str(tmp_path / 'out'), '--robots-max', '2',
                          '--draws', '1', '--goals-per-robot', '1', '--workers', '2',
                          '--controller', 'model,servo')
    assert compared.returncode == 0, compared.stderr
    summary = json.loads((tmp_path / 'out' / 'summary.json').read_text())
    assert [s['controller'] for s in summary['controllers']] == ['model', 'servo']
    assert summary['contacts'] == 0
    for each in summary['controllers']:
        assert [e['robots'] for e in each['per_robot_count']] == [1, 2]
        assert all(e['done'] == 1 for e in each['per_robot_count'])
    rows = (tmp_path / 'out' / 'runs.csv').read_text().splitlines()[1:]
    assert sorted(row.split(',')[:3] for row in rows) == [
        [robots, mode, '0'] for robots in ('1', '2') for mode in ('model', 'servo')]
    # The servo corrects on the way: more goals per minute than the model mode on the same
    # tasks (docs/fleet.md's table), so the two lines are not one summary written twice.
    model, servo = ([e['goals_per_minute_mean'] for e in each['per_robot_count']]
                    for each in summary['controllers'])
    assert all(fast > slow for fast, slow in zip(servo, model, strict=True))
    assert 'every robot in the model mode:' in compared.stdout
    assert 'every robot in the servo mode:' in compared.stdout
    assert (tmp_path / 'out' / 'throughput.png').read_bytes()[:4] == b'\x89PNG'


def test_the_study_tells_how_far_robots_driven_open_loop_stray_beside_the_papers_rule(tmp_path):
    """The same task sets, every robot open loop: one move per leg, so goals come sooner, and
    nothing keeps a robot on its lane (measured: 2.1 mm off a leg, 0.15 mm on the paper's rule;
    the plan leaves 1.5 mm)."""
    compared = omni_micro('fleet-study', '--out', str(tmp_path / 'out'), '--robots-max', '2',
                          '--draws', '1', '--goals-per-robot', '1', '--workers', '2',
                          '--controller', 'paper,open-loop')
    assert compared.returncode == 0, compared.stderr
    paper, open_loop = json.loads((tmp_path / 'out' / 'summary.json').read_text())['controllers']
    assert (paper['controller'], open_loop['controller']) == ('paper', 'open-loop')
    margin_mm = (CLEARANCE_M - ROBOT_DIAMETER_M) / 2.0 * 1e3
    assert open_loop['farthest_off_leg_mm'] > margin_mm > paper['farthest_off_leg_mm']
    for closed, opened in zip(paper['per_robot_count'], open_loop['per_robot_count'],
                              strict=True):
        assert opened['goals_per_minute_mean'] > closed['goals_per_minute_mean']
    assert 'every robot driven open loop:' in compared.stdout


@pytest.mark.parametrize('verb', [['fleet', '--graph', '--robots', '3'], ['run']])
def test_composed_takes_a_count_of_containers_or_leaves_it_to_the_graph(verb):
    """``--composed`` alone: the graph chooses (None); ``--composed 3``: three; 0 or a word is
    refused in one line, before anything starts."""
    parser = build_parser()
    for given, containers in (([], None), (['--composed'], None), (['--composed', '3'], 3)):
        args = parser.parse_args([*verb, *given])
        assert composition_of(args) == {'composed': bool(given), 'containers': containers}
    for count in ('0', 'two'):
        refused = omni_micro(*verb, '--composed', count)
        assert refused.returncode == 2 and '--composed: expected a whole number' in \
            refused.stderr and refused.stderr.count('\n') == 1, refused.stderr


def test_a_fleet_run_is_recorded_per_robot_replayed_one_robot_and_analyzed(tmp_path):
    from omni_micro_tools.bag_reading import read_bag

    bag = tmp_path / 'fleet'
    done = omni_micro('fleet', '--robots', '3', '--goals-per-robot', '1', '--seed', '2',
                      '--record', str(bag), '--json')
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout.strip().splitlines()[-1])
    data = read_bag(bag)
    assert set(data.messages) == {'/clock'} | {f'/robot_{k}/{topic}' for k in range(3)
                                               for topic in ('odom', 'goal_pose',
                                                             'controller/status')}
    for k, robot in enumerate(summary['robots']):
        odometry = data.messages[f'/robot_{k}/odom']
        # REP-105 frames per robot; the last sample where the run left the robot.
        assert {(m.header.frame_id, m.child_frame_id) for m in odometry} == {
            (f'robot_{k}/odom', f'robot_{k}/base_link')}
        final = odometry[-1].pose.pose.position
        assert final.x * 1e3 == pytest.approx(robot['final_mm'][0], abs=1e-3)
        assert final.y * 1e3 == pytest.approx(robot['final_mm'][1], abs=1e-3)
        # Each goal its controller was handed, as the graph's coordinator sends them: the
        # points of its legs, at most 24 mm apart (the paper's rule), the last its task's goal;
        # each ended reached, once, at the time the next is stamped with.
        # A task where the robot starts is done at 0 with no leg: no goal is handed out (as
        # robot 1's of this seed).
        goals = data.messages.get(f'/robot_{k}/goal_pose', [])
        if robot['legs'] == 0:
            assert goals == [] and robot['reached_at_s'] == [0.0]
            continue
        points = [(goal.pose.position.x * 1e3, goal.pose.position.y * 1e3) for goal in goals]
        assert points[-1] == pytest.approx(robot['goal_results'][0]['goal_mm'], abs=1e-9)
        start = robot['start_mm']
        assert all(math.dist(a, b) <= 24.0 + 1e-6
                   for a, b in itertools.pairwise([start, *points]))
        ends = data.messages[f'/robot_{k}/controller/status']
        assert [status.message for status in ends] == ['reached'] * len(goals)
        ended_s = [float({item.key: item.value for item in status.values}[STATUS_TIME_KEY])
                   for status in ends]
        assert [goal.header.stamp.sec + goal.header.stamp.nanosec * 1e-9 for goal in goals] \
            == pytest.approx([0.0, *ended_s[:-1]], abs=1e-9)
        assert ended_s[-1] == pytest.approx(robot['reached_at_s'][-1], abs=1e-9)
        # In the frame the graph's goals are in: a controller_node (frame_id 'platform')
        # rejects a goal in any other, replayed to it (docs/graph.md).
        assert {goal.header.frame_id for goal in goals} == {'platform'}
    stamps = data.timestamps['/robot_0/odom']
    assert all(later - earlier == 100_000_000 for earlier, later in itertools.pairwise(stamps))
    # In this pytest process's own DDS domain (tests/conftest.py).
    replayed = omni_micro('replay', str(bag), '--robot', '2', '--rate', '100')
    assert replayed.returncode == 0, replayed.stderr
    count = sum(len(data.raw[f'/robot_2/{topic}'])
                for topic in ('odom', 'goal_pose', 'controller/status'))
    assert f'replayed {count} messages on 3 topics' in replayed.stderr
    refused = omni_micro('replay', str(bag), '--robot', '5')
    assert refused.returncode == 2
    assert refused.stderr.strip() == ('omni-micro replay: error: --robot 5: the bag has no '
                                      '/robot_5/ topics (its robots: robot_0, robot_1, robot_2)')
    analyzed = omni_micro('analyze', str(bag), '--out', str(tmp_path / 'analysis'),
                          '--animate', '--frames', '3')
    assert analyzed.returncode == 0, analyzed.stderr
    # Every robot drawn, each in its colour (its chassis half transparent on white).
    from matplotlib.image import imread

    from omni_micro_vision.scene import FLEET_COLOURS

    assert getattr(Image.open(tmp_path / 'analysis' / 'run.gif'), 'n_frames', 1) == 3
    pixels = imread(tmp_path / 'analysis' / 'run_last_frame.png')[:, :, :3].reshape(-1, 3)
    for k in range(3):
        blended = (np.array(FLEET_COLOURS[k][:3]) + 1.0) / 2.0
        assert np.any(np.all(np.abs(pixels - blended) < 0.02, axis=1)), f'robot_{k} not drawn'
    table = json.loads((tmp_path / 'analysis' / 'summary.json').read_text())['robots']
    assert [row['robot'] for row in table] == ['robot_0', 'robot_1', 'robot_2']
    bag_length_s = (max(data.timestamps['/clock']) - min(data.timestamps['/clock'])) * 1e-9
    for k, (row, robot) in enumerate(zip(table, summary['robots'], strict=True)):
        # Its goal poses, every one reached; the last its task's goal.
        poses = len(data.messages.get(f'/robot_{k}/goal_pose', []))
        assert row['goals'] == row['goals_reached'] == poses
        if not poses:
            assert row['set_out_s'] is None and row['last_goal_deviation_um'] is None
            continue
        assert row['last_goal_deviation_um'] == pytest.approx(robot['deviation_um'][0], abs=0.5)
        # Each robot's own times, as the run had them: not the bag's length for every robot.
        assert row['set_out_s'] == 0.0
        assert row['reached_at_s'][-1] == pytest.approx(robot['reached_at_s'][-1], abs=1e-9)
        assert row['duration_s'] == pytest.approx(robot['reached_at_s'][-1], abs=1e-9)
    assert min(row['duration_s'] for row in table if row['duration_s'] is not None) \
        < bag_length_s - 1.0
    assert (tmp_path / 'analysis' / 'route.png').exists()
    assert '| robot_1 | 0/0 | - | - | - |' in analyzed.stdout and '| no goal |' in analyzed.stdout
    poses = len(data.messages['/robot_2/goal_pose'])
    assert f'| robot_2 | {poses}/{poses} | 0.00 |' in analyzed.stdout


def test_the_study_runs_on_an_existing_dask_scheduler_as_on_its_own_cluster(tmp_path):
    """--scheduler: the runs go to that scheduler's workers, with the rows a run in this
    process gives (the fleet twin is deterministic); an unreachable one is one line, exit 2."""
    from distributed import LocalCluster

    from omni_micro_studies.fleet_throughput import one_run

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host='127.0.0.1',
                      dashboard_address=None) as cluster:
        done = omni_micro('fleet-study', '--out', str(tmp_path / 'crossing'), '--crossing', '2',
                          '--seed', '3', '--scheduler', cluster.scheduler_address)
    assert done.returncode == 0, done.stderr
    assert f'2 fleet runs on the scheduler {cluster.scheduler_address}' in done.stderr
    rows = (tmp_path / 'crossing' / 'runs.csv').read_text().splitlines()[1:]
    expected = [one_run(4, seed, 2, True) for seed in (3, 4)]
    assert [row.rsplit(',', 1)[0] for row in rows] == [
        ','.join(str(v) for k, v in row.items() if k != 'wall_s') for row in expected]
    refused = omni_micro('fleet-study', '--out', str(tmp_path / 'none'), '--crossing', '1',
                         '--scheduler', 'tcp://127.0.0.1:9', '--scheduler-timeout', '1')
    assert refused.returncode == 2 and 'cannot connect' in refused.stderr
    assert 'Traceback' not in refused.stderr and not (tmp_path / 'none').exists()
