"""A fleet through the node graph (`fleet --graph`): three robots crossing each other's
goals, each its own controller (the model mode, the servo, the paper's rule), one dynamics_node
for all, each robot's vision_node and controller_node under /robot_k: every goal reached within
its tolerance, no two discs ever touching, the run the fleet twin runs, and the same run, goal
for goal and micrometre for micrometre, as fast as the lockstep allows and at twice real time
with both cores kept busy and composed (the dynamics in one container, the robots' nodes in
another), recorded into the same bag byte for byte (docs/fleet.md, "Through the node graph")."""

from __future__ import annotations

import asyncio
import json
import math
import socket
import threading
import time
from pathlib import Path

import pytest
from conftest import NoDeaths
from diagnostic_msgs.msg import DiagnosticStatus
from fleet_runs import assert_same_bag_file
from foxglove_client import free_port, watch
from geometry_msgs.msg import PoseStamped

from omni_micro_vision.scene import FLEET_COLOURS

ROBOTS = """robots:
  - start_mm: [30, 0]
    wheel_offsets_deg: [0, 3, 2]
    controller: model
  - start_mm: [70, 0]
    wheel_offsets_deg: [1, -2, 0]
    controller: servo
  - start_mm: [50, 24]
"""
CONTROLLERS = ['model', 'servo', 'paper']
# Each to where another starts or passes: every path crosses another's.
TASKS = """tasks:
  robot_0:
    - goal_mm: [70, 0]
  robot_1:
    - goal_mm: [30, 0]
  robot_2:
    - goal_mm: [50, -24]
"""
GOALS_MM = [(70.0, 0.0), (30.0, 0.0), (50.0, -24.0)]


def fleet_run(omni_micro, folder: Path, *extra: str) -> dict:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / 'robots.yaml').write_text(ROBOTS)
    (folder / 'tasks.yaml').write_text(TASKS)
    done = omni_micro('fleet', '--robots', str(folder / 'robots.yaml'), '--tasks',
                      str(folder / 'tasks.yaml'), '--seed', '5', '--json', *extra)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def fleet_through_graph(omni_micro, folder: Path, *extra: str) -> dict:
    summary = fleet_run(omni_micro, folder, '--graph', '--log-dir', str(folder / 'logs'),
                        '--record', str(folder / 'bag'), '--markers', *extra)
    (logs,) = (folder / 'logs').iterdir()
    if '--composed' in extra:   # the dynamics in one container, every robot's nodes in another
        processes = ['bag_recorder.log', 'loop_container.log', 'loop_container_1.log']
    else:   # one dynamics process for all, each robot's two nodes in their namespace
        processes = ['bag_recorder.log', 'dynamics_node.log',
                     *(f'robot_{k}.{node}.log' for k in range(3)
                       for node in ('controller_node', 'markers_node', 'vision_node'))]
    if '--view' in extra:   # the live view, a process of its own
        processes = sorted([*processes, 'viewer.log'])
    assert sorted(path.name for path in logs.glob('*.log')) == processes
    assert '3 robots (robot_0, robot_1, robot_2)' in (logs / processes[1]).read_text()
    return summary


@pytest.fixture(scope='module')
def as_fast_as_it_goes(omni_micro, tmp_path_factory) -> dict:
    folder = tmp_path_factory.mktemp('fleet') / 'max'
    return {**fleet_through_graph(omni_micro, folder), 'bag': folder / 'bag'}


def test_three_robots_cross_through_the_graph_clear_of_each_other(as_fast_as_it_goes):
    fastest = as_fast_as_it_goes
    assert fastest['outcome'] == 'done', fastest['reason']
    # Clear of each other all along (9 mm discs; the planner keeps centres 12 mm apart, each
    # robot within 1.5 mm of its legs).
    assert fastest['closest_gap_mm'] > 9.0
    for robot, goal, controller in zip(fastest['robots'], GOALS_MM, CONTROLLERS, strict=True):
        assert robot['goals_reached'] == 1 and robot['outcome'] == 'done'
        assert robot['controller'] == controller
        # Outside the micro field: reached to the macro camera's 50 um, true distance.
        assert robot['deviation_um'][0] < 50.0
        assert math.dist(robot['final_mm'], goal) < 0.05
        assert robot['farthest_off_leg_mm'] < 1.5


def test_the_graph_runs_what_the_fleet_twin_runs(as_fast_as_it_goes, omni_micro, tmp_path):
    """The fleet twin, in one process, is the graph's behaviour: every robot ends where the
    graph ends it, its goal reached at the same time after as many moves, the model mode and
    the servo having learnt the same offsets of their robot; and the twin's bag holds the goals
    the graph's coordinator handed out, each ended at the same time, so that analyze reads the
    two bags alike."""
    from omni_micro_tools.fleet_analysis import summarize_fleet

    graph = as_fast_as_it_goes
    twin = fleet_run(omni_micro, tmp_path / 'twin', '--record', str(tmp_path / 'twin' / 'bag'))
    tables = [summarize_fleet(bag, [0, 1, 2])[0]['robots']
              for bag in (tmp_path / 'twin' / 'bag', graph['bag'])]
    for in_twin, in_graph in zip(*tables, strict=True):
        assert in_twin['goals'] == in_graph['goals'] > 1   # the points of its legs
        assert in_twin['goals_reached'] == in_graph['goals_reached'] == in_twin['goals']
        assert in_twin['reached_at_s'] == pytest.approx(in_graph['reached_at_s'], abs=1e-9)
    assert twin['outcome'] == graph['outcome'] == 'done'
    assert twin['sim_time_s'] == pytest.approx(graph['sim_time_s'], abs=1e-9)
    for in_twin, in_graph in zip(twin['robots'], graph['robots'], strict=True):
        assert in_twin['final_mm'] == pytest.approx(in_graph['final_mm'], abs=1e-6)
        assert in_twin['reached_at_s'] == pytest.approx(in_graph['reached_at_s'], abs=1e-9)
        assert in_twin['moves'] == in_graph['moves']
        if in_twin['controller'] == 'paper':
            assert in_twin['learnt_offsets_deg'] is in_graph['learnt_offsets_deg'] is None
        else:
            assert in_twin['learnt_offsets_deg'] == pytest.approx(
                in_graph['learnt_offsets_deg'], abs=1e-9)


def test_the_bag_holds_every_robot_under_its_namespace_to_the_last_goal(as_fast_as_it_goes):
    from omni_micro_tools.bag_reading import read_bag
    from omni_micro_tools.fleet_analysis import fleet_robots, summarize_fleet

    summary, bag = as_fast_as_it_goes, as_fast_as_it_goes['bag']
    own = ('odom', 'goal_pose', 'camera/macro/pose', 'camera/macro/pose_in_motion',
           'controller/status', 'markers')
    data = read_bag(bag, topics=['/clock', *(f'/robot_{k}/{topic}' for k in range(3)
                                              for topic in own)])
    assert fleet_robots(list(data.timestamps)) == [0, 1, 2]
    end_s = summary['sim_time_s'] + 0.5    # the last goal's end and the bag's tail
    clock = [m.clock.sec + m.clock.nanosec * 1e-9 for m in data.messages['/clock']]
    assert clock[0] == 0.02 and abs(clock[-1] - end_s) < 0.021   # from the first tick
    for k, robot in enumerate(summary['robots']):
        odometry = data.messages[f'/robot_{k}/odom']
        # Every tick (50 Hz), in the robot's own REP-105 frames.
        assert len(odometry) == len(clock)
        assert (odometry[0].header.frame_id, odometry[0].child_frame_id) == (
            f'robot_{k}/odom', f'robot_{k}/base_link')
        last = odometry[-1].pose.pose.position
        assert math.dist((last.x * 1e3, last.y * 1e3), robot['final_mm']) < 1e-3
        # Its legs' goals (sub-goals on the way), the task's last.
        # In the frame the twin's bag puts them (tests/cli/test_fleet_cli.py).
        assert {m.header.frame_id for m in data.messages[f'/robot_{k}/goal_pose']} == {
            'platform'}
        last_goal = data.messages[f'/robot_{k}/goal_pose'][-1].pose.position
        assert math.dist((last_goal.x * 1e3, last_goal.y * 1e3), GOALS_MM[k]) < 1e-9
        assert data.messages[f'/robot_{k}/camera/macro/pose']
        # The servo's vision_node publishes the captures in motion it reads, recorded beside.
        assert bool(data.messages.get(f'/robot_{k}/camera/macro/pose_in_motion')) == (
            robot['controller'] == 'servo')
        outcomes = [m.message for m in data.messages[f'/robot_{k}/controller/status']]
        assert outcomes[-1] == 'reached'
        # Drawn by its own markers_node: its chassis in its colour (tab10, as fleet --plot
        # draws its route), labelled with its name, where the robot ended.
        drawn = {(m.ns, m.id): m for array in data.messages[f'/robot_{k}/markers']
                 for m in array.markers}
        chassis, label = drawn[('robot/chassis', 0)], drawn[('robot/label', 0)]
        assert (chassis.color.r, chassis.color.g, chassis.color.b) == pytest.approx(
            FLEET_COLOURS[k][:3])
        assert label.text == f'robot_{k}'
        assert math.dist((chassis.pose.position.x * 1e3, chassis.pose.position.y * 1e3),
                         robot['final_mm']) < 0.01
    # analyze's table per robot reads it as it reads the fleet twin's bag.
    table, _ = summarize_fleet(bag, [0, 1, 2])
    for k, (row, robot) in enumerate(zip(table['robots'], summary['robots'], strict=True)):
        assert row['goals'] == len(data.messages[f'/robot_{k}/goal_pose'])
        assert row['last_goal_deviation_um'] < 50.0
        assert math.dist((row['final_x_mm'], row['final_y_mm']), robot['final_mm']) < 1e-3


def test_the_same_fleet_run_composed_at_twice_real_time_with_both_cores_busy_and_watched_live(
        as_fast_as_it_goes, omni_micro, tmp_path, busy_machine):
    """Against the run at full speed in separate processes: composed in two containers (the
    dynamics in one, the robots' nodes in the other), paced at twice real time beside two busy
    processes, and watched live, the same run and bag. Two
    robots' goals ended at the same stamp once, and the coordinator's word for one released the
    other's before its next goal was taken (robot 0 started 0.17 s later at full speed): each
    robot has its own coordinator in the lockstep since. The Foxglove client (--view) changes
    nothing. (One run for the three: a composed run of its own cost a fleet run more, and this
    one, in separate processes, took 61.4 s of CPU in one suite run, over the 60 s a test may.)"""
    port = free_port()
    received: dict[str, list] = {}

    def watch_until_the_graph_stops() -> None:
        # Connects once the view is up; reads until the graph stops it (or 5 minutes).
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline:
            with socket.socket() as sock:
                if sock.connect_ex(('127.0.0.1', port)) == 0:
                    break
            time.sleep(0.05)
        received.update(asyncio.run(watch(f'ws://127.0.0.1:{port}', 300.0, lambda _: False,
                                          then_slow_s=0.0)))
    watcher = threading.Thread(target=watch_until_the_graph_stops, daemon=True)
    watcher.start()
    with busy_machine():
        paced = fleet_through_graph(omni_micro, tmp_path / 'rtf2', '--rtf', '2', '--composed',
                                    '2', '--view', '--view-port', str(port))
    watcher.join(timeout=60)
    assert_the_same_run_and_bag(as_fast_as_it_goes, paced, tmp_path / 'rtf2')
    for k in range(3):
        # Each robot drawn in its colour and seen moving, under its namespace.
        (chassis, *_) = [m for array in received[f'/robot_{k}/markers'] for m in array.markers
                         if m.ns == 'robot/chassis']
        assert (chassis.color.r, chassis.color.g, chassis.color.b) == pytest.approx(
            FLEET_COLOURS[k][:3])
        assert received[f'/robot_{k}/odom'][-1].header.frame_id == f'robot_{k}/odom'
    assert received['/clock'] and '/odom' not in received


def assert_the_same_run_and_bag(reference: dict, other: dict, folder: Path) -> None:
    """The same JSON but its wall times, and the same bag file, byte for byte."""
    expected = dict(reference)
    bag = expected.pop('bag')
    for summary in (expected, other):
        del summary['wall_s'], summary['planning_s'], summary['running_wall_s']
    assert other == expected
    assert_same_bag_file(bag, folder / 'bag')


def test_a_fleet_goal_waits_for_its_controller_not_for_the_recorder_that_listened_first(
        probe, domain_id, tmp_path):
    """The recorder's reader of /robot_0/goal_pose can match before the controller's: a goal
    sent then is the recorder's alone, and the controller never takes it (a CI run: "robot_0's
    controller_node did not take its goal within 30 s"). Stand-ins: the recorder, listening at
    once; the controller, answering its tolerance and only a second later reading goals."""
    from rcl_interfaces.msg import SetParametersResult
    from rclpy.node import Node
    from rclpy.timer import Timer

    from omni_micro_bringup.fleet_coordinator import FleetCoordinator
    from omni_micro_common.qos import STATUS_QOS as CONTROLLER_STATUS_QOS
    from omni_micro_control.fleet_legs import GoalOrder

    recorded: list[PoseStamped] = []
    recorder = Node('bag_recorder', context=probe.context)
    recorder.create_subscription(PoseStamped, '/robot_0/goal_pose', recorded.append, 10)
    controller = Node('controller_node', namespace='robot_0', context=probe.context)
    for standin in (recorder, controller):
        probe.executor.add_node(standin)
    controller.declare_parameter('tolerance_m', 0.001)
    status = controller.create_publisher(DiagnosticStatus, '/robot_0/controller/status',
                                         CONTROLLER_STATUS_QOS)
    taken: list[PoseStamped] = []

    def take(goal: PoseStamped) -> None:
        taken.append(goal)
        status.publish(DiagnosticStatus(message='settling'))

    def listen_late() -> None:
        late_listener.pop().cancel()
        controller.create_subscription(PoseStamped, '/robot_0/goal_pose', take, 10)

    late_listener: list[Timer] = []

    def on_tolerance(_: object) -> SetParametersResult:
        late_listener.append(controller.create_timer(1.0, listen_late))
        return SetParametersResult(successful=True)

    controller.add_on_set_parameters_callback(on_tolerance)
    monitor = FleetCoordinator(domain_id, 1, recording=True)
    try:
        with probe.spinning():
            monitor.give(NoDeaths(tmp_path), GoalOrder(0, (0.01, 0.02), 0.0005, stamp_s=1.5),
                         timeout_s=10.0)
            recorder_waited = time.monotonic() + 5.0
            while not recorded and time.monotonic() < recorder_waited:
                time.sleep(0.05)
        assert controller.get_parameter('tolerance_m').value == 0.0005
    finally:
        monitor.close()
        for standin in (recorder, controller):
            standin.destroy_node()
    # Once each, at the stamp it was given: sent again, the controller would end the first as
    # replaced, and the bag would hold it twice.
    assert [(goal.pose.position.x, goal.pose.position.y, goal.header.stamp.sec,
             goal.header.stamp.nanosec) for goal in taken + recorded] == [
        (0.01, 0.02, 1, 500_000_000)] * 2


def test_a_fleet_run_stops_at_its_simulated_time_on_the_clock_as_the_twin_does(omni_micro,
                                                                              tmp_path):
    """--max-sim-time is looked at on the robots' clock, as the twin looks at it each step, not
    only when a goal ends: drawn goals that take 25 s stop at the first tick past 8 s, the
    twin's, whenever the orchestration reads the clock (exit 1, tasks left, the JSON says when,
    and what was done by then is the twin's)."""
    runs = [omni_micro('fleet', *graph, '--robots', '3', '--seed', '1', '--goals-per-robot',
                       '1', '--max-sim-time', '8', '--json', '--log-dir', str(tmp_path / 'logs'))
            for graph in (('--graph',), ())]
    summaries = []
    for stopped in runs:
        assert stopped.returncode == 1, stopped.stderr[-2000:]
        assert 'tasks left after 8 s of simulated time' in stopped.stderr
        summaries.append(json.loads(stopped.stdout.strip().splitlines()[-1]))
    graph, twin = summaries
    assert graph['outcome'] == twin['outcome'] == 'timeout'
    assert graph['sim_time_s'] == pytest.approx(twin['sim_time_s'], abs=1e-9) \
        == pytest.approx(8.02, abs=1e-9)
    assert [(robot['reached_at_s'], robot['moves']) for robot in graph['robots']] == \
        [(robot['reached_at_s'], robot['moves']) for robot in twin['robots']]


OPEN_LOOP_ROBOTS = ('robots:\n  - start_mm: [0, 0]\n    controller: open-loop\n'
                    '  - start_mm: [0, 40]\n')
OPEN_LOOP_TASKS = ('tasks:\n  robot_0:\n    - goal_mm: [60, 0]\n    - goal_mm: [60, 30]\n'
                   '  robot_1:\n    - goal_mm: [60, 60]\n')


def test_an_open_loop_robot_beside_a_closed_loop_one_runs_through_the_graph_as_in_the_twin(
        omni_micro, tmp_path):
    """A robot of a fleet driven open loop (one move per leg, its end 'completed') through the
    graph: the same goals at the same simulated times, the same drift, as the twin's; and one
    robot driven so alone, through ``run``, completes."""
    (tmp_path / 'robots.yaml').write_text(OPEN_LOOP_ROBOTS)
    (tmp_path / 'tasks.yaml').write_text(OPEN_LOOP_TASKS)
    runs = [omni_micro('fleet', *graph, '--robots', str(tmp_path / 'robots.yaml'), '--tasks',
                       str(tmp_path / 'tasks.yaml'), '--seed', '1', '--json', '--log-dir',
                       str(tmp_path / 'logs')) for graph in (('--graph',), ())]
    summaries = []
    for done in runs:
        assert done.returncode == 0, done.stderr[-2000:]
        summaries.append(json.loads(done.stdout.strip().splitlines()[-1]))
    graph, twin = summaries
    assert graph['sim_time_s'] == pytest.approx(twin['sim_time_s'], abs=1e-9)
    for in_graph, in_twin in zip(graph['robots'], twin['robots'], strict=True):
        assert (in_graph['controller'], in_graph['reached_at_s'], in_graph['moves']) == \
            (in_twin['controller'], in_twin['reached_at_s'], in_twin['moves'])
        assert in_graph['deviation_um'] == pytest.approx(in_twin['deviation_um'], abs=1e-3)
    open_loop = graph['robots'][0]
    assert open_loop['moves'] == open_loop['legs']   # one move per leg, no correction
    alone = omni_micro('run', '--goal-mm', '30,0', '--controller', 'open-loop', '--rtf', 'max',
                       '--json', '--log-dir', str(tmp_path / 'logs'))
    assert alone.returncode == 0, alone.stderr[-2000:]
    summary = json.loads(alone.stdout.strip().splitlines()[-1])
    # One move, 0.44 mm off after 30 mm (the default robot's offsets), no correction after.
    assert summary['outcome'] == 'completed' and summary['periods'] == 1
    assert summary['deviation_mm'] > 0.1


def test_a_fleet_whose_controllers_read_bare_captures_runs_as_the_twin_does(omni_micro,
                                                                           tmp_path):
    """``capture_uncertainty: fixed`` (a camera without covariance; the paper's rule decides
    alike on either): each robot's vision_node waits for its controller and markers_node on the
    bare captures they read, the graph comes up and every robot reaches its goal when and
    where the twin's does. (Their cameras waited for them on the covariance topics: the graph
    never came up, "nobody subscribes /robot_0/camera/macro/pose_with_covariance".)"""
    params = tmp_path / 'bare.yaml'
    params.write_text('controller_node:\n  ros__parameters:\n    capture_uncertainty: fixed\n'
                      '    fixed_uncertainty:\n      macro: [1.0e-5, 1.0e-5, 0.001]\n'
                      '      micro: [1.0e-7, 1.0e-7, 0.0001]\n')
    drawn = ('--robots', '2', '--seed', '1', '--goals-per-robot', '1', '--json')
    runs = [omni_micro('fleet', *drawn, *graph) for graph in (
        ('--graph', '--markers', '--params', str(params), '--log-dir', str(tmp_path / 'logs')),
        ())]
    summaries = []
    for done in runs:
        assert done.returncode == 0, done.stderr[-2000:]
        summaries.append(json.loads(done.stdout.strip().splitlines()[-1]))
    graph, twin = summaries
    assert graph['outcome'] == twin['outcome'] == 'done'
    for in_graph, in_twin in zip(graph['robots'], twin['robots'], strict=True):
        assert (in_graph['reached_at_s'], in_graph['moves']) == (in_twin['reached_at_s'],
                                                                 in_twin['moves'])
        assert in_graph['deviation_um'] == pytest.approx(in_twin['deviation_um'], abs=1e-3)
    (logs,) = (tmp_path / 'logs').iterdir()
    assert 'capture_readers:=[robot_0/controller_node,robot_0/markers_node]' in (
        logs / 'robot_0.vision_node.log').read_text()
