"""Bringing respawned nodes back (Respawns, against a stand-in orchestration): one way for the
single robot (its nodes in the root namespace, robot 0) and a fleet's (``robot_1.vision_node``).
The goal under way is given again, unless it ended in a status not handled yet; a new camera is
watched until its controller acts: the end of the goal replaced by the same one given again is
not an act, a move is; the goal is given again every 3 s meanwhile, and the watch ends there."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.respawns import CameraWatch, Respawns
from omni_micro_control.feedback import REPLACED_REASON
from omni_micro_control.fleet_legs import GoalOrder


class Orchestration:
    """What Respawns reads and calls of the orchestration's node, the clock held or started
    and the ROS graph's readers as a fresh process's (every endpoint is new)."""

    def __init__(self) -> None:
        self.statuses: list[tuple[int, dict[str, str]]] = []
        self.given: list[tuple[int, Any]] = []
        self.paused: list[bool] = []
        self.echo = None
        self.node = self

    def give_again(self, graph: Any, robot: int, goal: Any) -> None:
        self.given.append((robot, goal))

    def set_paused(self, graph: Any, paused: bool) -> None:
        self.paused.append(paused)

    def spin_for(self, seconds: float) -> None:
        """Nothing to spin."""

    def let_matching_settle(self) -> None:
        """Nothing to settle."""

    def simulated_time_s(self) -> float:
        return time.monotonic()   # time moves as soon as the clock is started

    def get_subscriptions_info_by_topic(self, topic: str) -> list[Any]:
        return []


class Graph:
    """A supervisor whose processes all live."""

    log_dir = Path('.')

    def check_alive(self) -> list[str]:
        return []

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return True


def bring_back(respawns: Respawns, restarted: list[str], driving: dict[int, Any],
               handled_up_to: int = 0) -> None:
    """As the orchestration does, its readers of the respawned nodes' topics not modelled: the
    new processes' readers count as found at once."""
    respawns._has_new_endpoints = lambda process: True   # type: ignore[method-assign]
    respawns.bring_back(Graph(), restarted, driving, handled_up_to)


def test_the_single_robot_s_new_camera_is_robot_0_s_and_its_goal_is_given_again():
    orchestration = Orchestration()
    respawns = Respawns(orchestration, ['vision_node'])   # type: ignore[arg-type]
    bring_back(respawns, ['vision_node'], {0: (0.1, 0.0)})
    # The clock held while the node came back, the goal given again, the clock started.
    assert orchestration.given == [(0, (0.1, 0.0))]
    assert orchestration.paused[0] is True and orchestration.paused[-1] is False
    assert 0 in respawns.watched
    orchestration.statuses.append((0, {'message': 'moving'}))
    respawns.watch_new_cameras(Graph(), {0: (0.1, 0.0)})
    assert 0 not in respawns.watched


def test_a_goal_that_ended_before_the_respawn_is_not_given_again():
    orchestration = Orchestration()
    orchestration.statuses.append((0, {'message': 'moving'}))
    orchestration.statuses.append((0, {'message': 'reached'}))   # not handled yet
    respawns = Respawns(orchestration, ['controller_node'])   # type: ignore[arg-type]
    bring_back(respawns, ['controller_node'], {0: (0.1, 0.0)}, handled_up_to=1)
    assert orchestration.given == [] and orchestration.paused == [True, False]
    # Handled already: the goal under way is given again.
    bring_back(respawns, ['controller_node'], {0: (0.1, 0.0)}, handled_up_to=2)
    assert orchestration.given == [(0, (0.1, 0.0))]


def test_a_fleet_robot_s_node_is_told_by_its_namespace():
    orchestration = Orchestration()
    respawns = Respawns(orchestration, ['robot_1.vision_node'])   # type: ignore[arg-type]
    order = GoalOrder(1, (0.03, 0.0), 50e-6, 4.0)
    bring_back(respawns, ['robot_1.vision_node'], {0: GoalOrder(0, (0.0, 0.0), 50e-6), 1: order})
    assert orchestration.given == [(1, order)] and list(respawns.watched) == [1]


def test_a_replaced_goal_is_no_act_a_move_is_and_the_leg_is_given_again_meanwhile():
    orchestration = Orchestration()
    respawns = Respawns(orchestration, ['robot_1.vision_node'])   # type: ignore[arg-type]
    order = GoalOrder(1, (0.03, 0.0), 50e-6, 4.0)
    driving = {1: order}
    respawns.watched[1] = CameraWatch(0, time.monotonic() - 3.1, 0)
    # The old goal ends as replaced by the same one, given again: no capture acted on yet.
    orchestration.statuses.append((1, {'message': 'cancelled', 'reason': REPLACED_REASON}))
    orchestration.statuses.append((0, {'message': 'moving'}))   # another robot's
    respawns.watch_new_cameras(Graph(), driving)
    assert orchestration.given == [(1, order)] and 1 in respawns.watched
    orchestration.statuses.append((1, {'message': 'moving'}))
    respawns.watch_new_cameras(Graph(), driving)
    assert 1 not in respawns.watched and orchestration.given == [(1, order)]


@pytest.mark.parametrize(('restarted', 'robot', 'named'), [
    ('robot_1.vision_node', 1, "robot_1's controller_node"),
    ('vision_node', 0, 'controller_node')])
def test_a_camera_never_acted_on_ends_the_run_naming_the_robot(restarted, robot, named):
    orchestration = Orchestration()
    respawns = Respawns(orchestration, [restarted])   # type: ignore[arg-type]
    bring_back(respawns, [restarted], {robot: (0.03, 0.0)})
    respawns.watched[robot] = CameraWatch(0, time.monotonic() - 3.1, 20)
    with pytest.raises(RunFailed, match=f'^{named} receives no capture from its respawned'):
        respawns.watch_new_cameras(Graph(), {robot: (0.03, 0.0)})
