"""A fleet robot's respawned camera watched until its controller acts (FleetRespawns, against a
stand-in coordinator): the end of the goal replaced by the same one given again is not an act,
a move is; the leg is given again every 3 s meanwhile, and the watch ends there."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.respawns import FleetRespawns
from omni_micro_control.feedback import REPLACED_REASON
from omni_micro_control.fleet_legs import GoalOrder


class Coordinator:
    """What FleetRespawns reads and calls of the coordinator's node."""

    def __init__(self) -> None:
        self.fleet_statuses: list[tuple[int, dict[str, str]]] = []
        self.given: list[GoalOrder] = []
        self.echo = None

    def give(self, graph: Any, order: GoalOrder, timeout_s: float = 30.0) -> None:
        self.given.append(order)


class Graph:
    """A supervisor whose processes all live."""

    log_dir = Path('.')

    def check_alive(self) -> list[str]:
        return []

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return True


def test_a_replaced_goal_is_no_act_a_move_is_and_the_leg_is_given_again_meanwhile():
    coordinator = Coordinator()
    respawns = FleetRespawns(coordinator, ['robot_1.vision_node'])   # type: ignore[arg-type]
    order = GoalOrder(1, (0.03, 0.0), 50e-6, 4.0)
    driving = {1: order}
    respawns.watched[1] = [0, time.monotonic() - 3.1, 0]
    # The old goal ends as replaced by the same one, given again: no capture acted on yet.
    coordinator.fleet_statuses.append((1, {'message': 'cancelled', 'reason': REPLACED_REASON}))
    coordinator.fleet_statuses.append((0, {'message': 'moving'}))   # another robot's
    respawns.watch_new_cameras(Graph(), driving)
    assert coordinator.given == [order] and 1 in respawns.watched
    coordinator.fleet_statuses.append((1, {'message': 'moving'}))
    respawns.watch_new_cameras(Graph(), driving)
    assert 1 not in respawns.watched and coordinator.given == [order]


def test_a_camera_never_acted_on_ends_the_run_naming_the_robot():
    coordinator = Coordinator()
    respawns = FleetRespawns(coordinator, ['robot_1.vision_node'])   # type: ignore[arg-type]
    respawns.watched[1] = [0, time.monotonic() - 3.1, 20]
    with pytest.raises(RunFailed, match="robot_1's controller_node receives no capture"):
        respawns.watch_new_cameras(Graph(), {1: GoalOrder(1, (0.03, 0.0), 50e-6)})
