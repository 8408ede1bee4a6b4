"""Faults in a fleet (docs/reliability.md, "Faults"): a robot's vision_node or
controller_node killed mid-run comes back with --respawn, its leg given again, and every task
is done with the robots clear of each other; dynamics_node killed, which no robot can do
without, stops the run within 5 s, named, every process stopped and the bag readable."""

from __future__ import annotations

import os
import signal
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import pause_the_robots_clock

from omni_micro_bringup.errors import RunFailed, UsageError
from omni_micro_bringup.graph import run_graph
from omni_micro_bringup.graph_options import FleetRun, GraphOptions
from omni_micro_control.fleet_plan import Task, plan_fleet
from omni_micro_control.fleet_roadmap import ROBOT_DIAMETER_M
from omni_micro_sim.parameters import RobotParameters
from omni_micro_tools.bag_reading import read_bag

# Two robots swapping places: each leg of one waits for the other's (18.5 s simulated).
STARTS_M = [(0.030, 0.0), (0.070, 0.0)]
GOALS_M = [(0.070, 0.0), (0.030, 0.0)]


def fleet_options(tmp_path: Path, **options: Any) -> GraphOptions:
    plan = plan_fleet(STARTS_M, [[Task(goal)] for goal in GOALS_M], seed=5)
    robots = [RobotParameters() for _ in STARTS_M]
    # Twice real time: the run lasts about 9 s of wall time, the kill lands mid-run whatever
    # the load.
    options.setdefault('real_time_factor', 2.0)
    return GraphOptions(seed=5, markers=False, log_dir=tmp_path / 'logs',
                        fleet=FleetRun(plan, robots, ['paper'] * len(robots)), **options)


def kill_after(process: str, wall_s: float, record: dict, hold_clock: bool = False):
    """SIGKILL to ``process`` ``wall_s`` after the clock starts; ``record`` gets when, and the
    graph."""
    def on_running(graph):
        record['graph'] = graph

        def kill():
            time.sleep(wall_s)
            if hold_clock:   # no message under way (test_reliability says why)
                pause_the_robots_clock(graph.domain_id)
                time.sleep(0.3)
            record['killed_at'] = time.monotonic()
            os.kill(graph.process(process).process.pid, signal.SIGKILL)
        threading.Thread(target=kill, daemon=True).start()
    return on_running


@pytest.mark.parametrize('process', ['robot_0.vision_node', 'robot_1.controller_node'])
def test_a_robots_node_killed_comes_back_and_every_task_is_done(process, tmp_path):
    lines: list[str] = []
    result = run_graph(fleet_options(tmp_path, respawn=True, echo=lines.append),
                       kill_after(process, 1.5, {}))
    assert result.respawns == {process: 1}, lines[-20:]
    assert result.outcome == 'done', result.reason
    assert [len(log.tasks_done_s) for log in result.robots] == [1, 1]
    # Each ended at its goal (the macro camera's 50 um), the discs never touching.
    for log, goal in zip(result.robots, GOALS_M, strict=True):
        _, x, y, _ = log.route[-1]
        assert abs(x - goal[0]) < 60e-6 and abs(y - goal[1]) < 60e-6
    assert result.closest_gap_m > ROBOT_DIAMETER_M
    assert any(f'{process} exited with -9; respawning it' in line for line in lines)
    # It was driving a leg, given again once it was back.
    robot = process.partition('.')[0]
    assert any(f"{robot}'s leg to" in line and 'given again' in line for line in lines), lines


def test_dynamics_killed_stops_the_fleet_named_with_the_bag_readable(tmp_path):
    events: dict = {}
    with pytest.raises(RunFailed, match='dynamics_node exited with code -9'):
        run_graph(fleet_options(tmp_path, record=tmp_path / 'bag'),
                  kill_after('dynamics_node', 1.5, events, hold_clock=True))
    assert time.monotonic() - events['killed_at'] < 5.0
    # Nothing left running.
    assert all(p.process.poll() is not None for p in events['graph'].processes)
    bag = read_bag(tmp_path / 'bag', topics=['/robot_0/odom', '/robot_1/odom'])
    assert all(len(bag.messages[topic]) > 10 for topic in ('/robot_0/odom', '/robot_1/odom'))


def test_respawn_with_composed_is_refused_for_a_fleet_too(tmp_path):
    with pytest.raises(UsageError, match='--respawn restarts a crashed node'):
        run_graph(fleet_options(tmp_path, respawn=True, composed=True))
    assert not (tmp_path / 'logs').exists()


def test_dropped_and_late_captures_in_a_fleet_still_do_every_task(tmp_path):
    """Each robot's vision_node loses three captures in ten (each its own draws) and publishes
    the rest 0.2 s late: latency costs time, never position or clearance."""
    faults = {'faults.drop_probability': 0.3, 'faults.delay_s': 0.2, 'faults.camera': 'both'}
    result = run_graph(fleet_options(tmp_path, real_time_factor=float('inf'),
                                     vision_overrides=faults))
    assert result.outcome == 'done', result.reason
    for log, goal in zip(result.robots, GOALS_M, strict=True):
        _, x, y, _ = log.route[-1]
        assert abs(x - goal[0]) < 60e-6 and abs(y - goal[1]) < 60e-6
    assert result.closest_gap_m > ROBOT_DIAMETER_M
    # Slower than without faults (18.5 s): every period waits 0.2 s more at least.
    assert result.sim_time_s > 20.0


def test_a_frozen_camera_in_a_fleet_ends_the_run_lost_naming_the_robot(tmp_path):
    faults = {'faults.frozen_after_s': 3.0, 'faults.camera': 'both'}
    result = run_graph(fleet_options(tmp_path, real_time_factor=float('inf'),
                                     vision_overrides=faults))
    assert result.outcome == 'lost'
    assert result.reason.startswith('robot ') and 'lost' in result.reason, result.reason
    assert result.sim_time_s >= 3.0
