"""A fleet's run told from what was logged of it (a run through the graph: each robot's
odometry, legs and tasks), as the fleet twin tells its own (:class:`~.fleet_twin.FleetResult`):
how far each robot strayed from its legs, how close it stopped to each goal, where it was when
the run ended."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from omni_micro_control.fleet_plan import FleetPlan, Leg
from omni_micro_control.fleet_roadmap import point_segment_distance
from omni_micro_sim.state import RobotState
from omni_micro_studies.fleet_twin import FleetResult, RobotRun


class LoggedRobot(Protocol):
    """What is needed of one robot's log (omni_micro_bringup.graph_result.RobotLog)."""

    tasks_done_s: list[float]
    moves: int
    outcome: str
    route: list[tuple[float, float, float, float]]   # t, x, y, phi
    legs: list[tuple[float, float, Leg]]              # started, ended, leg
    learnt_offsets_rad: tuple[float, float] | None
    goal_poses: list[tuple[float, float, float]]     # stamp_s, x_m, y_m
    goal_pose_ends: list[tuple[float, str]]           # at_s, outcome


class LoggedRun(Protocol):
    """What is needed of the run (omni_micro_bringup.graph_result.GraphResult)."""

    outcome: str
    reason: str
    sim_time_s: float
    closest_gap_m: float
    closest_pair: tuple[int, int] | None

    @property
    def robots(self) -> Sequence[LoggedRobot]: ...


def told_as_the_twin(plan: FleetPlan, run: LoggedRun) -> FleetResult:
    """``run`` as the fleet twin tells its own, ``plan`` the plan it drove."""
    robots = []
    for k, log in enumerate(run.robots):
        route = np.array(log.route) if log.route else np.zeros((0, 4))
        off_leg = 0.0
        for started, ended, leg in log.legs:
            during = route[(route[:, 0] >= started) & (route[:, 0] <= ended)] \
                if len(route) else route
            if len(during):
                off_leg = max(off_leg, float(np.max(point_segment_distance(
                    during[:, 1:3], np.array(leg.start_m), np.array(leg.end_m)))))
        deviations = []
        for done_s, goal in zip(log.tasks_done_s, [task.goal_m for task in plan.tasks[k]],
                                strict=False):
            after = route[route[:, 0] >= done_s] if len(route) else route
            deviations.append(math.dist(after[0, 1:3], goal) if len(after) else math.nan)
        # Where it was when the run ended (a robot at rest still creeps by 1e-14 m a tick: the
        # last sample received would depend on when the graph was stopped).
        at_end = route[route[:, 0] >= run.sim_time_s] if len(route) else route
        final = at_end[0] if len(at_end) else (0.0, *plan.starts_m[k], 0.0)
        robots.append(RobotRun(k, len(log.legs), log.tasks_done_s, deviations, log.moves,
                               off_leg, log.outcome,
                               RobotState(x_m=float(final[1]), y_m=float(final[2]),
                                          phi_rad=float(final[3])), route,
                               log.learnt_offsets_rad, log.goal_poses, log.goal_pose_ends))
    return FleetResult(run.outcome, run.reason, run.sim_time_s, robots, run.closest_gap_m,
                       run.closest_pair)
