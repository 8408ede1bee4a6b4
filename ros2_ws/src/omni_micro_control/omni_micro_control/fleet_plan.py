"""A plan for several robots on one platform: who drives where, and who waits for whom.

The platform is reserved on a roadmap (:mod:`omni_micro_control.fleet_roadmap`). Prioritized
planning gives every robot in turn a path of synchronous steps that keeps clear of the paths
and final places of the robots planned before it (space-time A*); when one cannot be found,
that robot is planned earlier and the plan tried again. Its paths are each robot's shortest
that the others leave free, but it is incomplete: a robot planned late may find every way
taken, whatever the order. After ``PRIORITY_ORDERS`` orders, LaCAM
(:mod:`omni_micro_control.fleet_lacam`), complete, plans the fleet on the roadmap with the
20 mm lanes of the drawn places added (robots resting on them leave room to pass between).
Steps take no fixed time on the platform: the action dependency graph
(:mod:`omni_micro_control.fleet_dependencies`) turns them into legs that wait for each other.

The micro field (2 mm) is smaller than a robot: the clearance alone gives it to one robot at
a time.
"""

from __future__ import annotations

import heapq
import itertools
import math
import random
from dataclasses import dataclass

from omni_micro_common.conventions import (
    GOAL_TOLERANCE_M,
    MICRO_FIELD_CENTER_M,
    MICRO_FIELD_SIZE_M,
)
from omni_micro_control.fleet_dependencies import (
    WAYPOINT_TOLERANCE_M,  # noqa: F401 (the planner's, as its callers know it)
    Leg,
    action_dependencies,
)
from omni_micro_control.fleet_lacam import NoPlanError, SearchEndedError, lacam_paths
from omni_micro_control.fleet_roadmap import (
    CLEARANCE_M,
    ROUNDING_M,
    Roadmap,
    build_roadmap,
    check_on_platform,
    distances_to,
)

# A goal the macro camera sees (outside the micro field) is reached this close.
MACRO_GOAL_TOLERANCE_M = 50.0e-6
# Steps a robot's path may take at most (a 150 mm platform is crossed in 15).
MAX_STEPS = 400
# Priority orders tried before LaCAM (4 per robot up to 4 robots, as they were before it).
PRIORITY_ORDERS = 16
# The pitch of the lanes LaCAM's roadmap adds: the lattice robots are drawn on.
LANES_M = 0.02
# Configurations LaCAM may keep before it gives up (42 robots take about 100).
LACAM_MAX_NODES = 100_000


class PlanningError(ValueError):
    """Tasks no plan can meet: a cycle of waits, two goals closer than the clearance."""


class PlannerGaveUpError(RuntimeError):
    """The search stopped at its bound without a plan: the tasks may have one."""


@dataclass(frozen=True)
class Task:
    """Reach ``goal_m``; with ``after`` = (robot, task index), not before that one is done."""

    goal_m: tuple[float, float]
    after: tuple[int, int] | None = None
    tolerance_m: float | None = None      # None: the micro's 3 um in its field, else 50 um

    def tolerance(self) -> float:
        return self.tolerance_m if self.tolerance_m is not None else self.default_tolerance_m()

    def default_tolerance_m(self) -> float:
        """The tolerance of a goal that gives none: the micro camera's in its field."""
        inside = all(abs(self.goal_m[axis] - MICRO_FIELD_CENTER_M[axis])
                     <= MICRO_FIELD_SIZE_M[axis] / 2.0 for axis in (0, 1))
        return GOAL_TOLERANCE_M if inside else MACRO_GOAL_TOLERANCE_M


@dataclass(frozen=True)
class FleetPlan:
    starts_m: tuple[tuple[float, float], ...]
    tasks: tuple[tuple[Task, ...], ...]
    legs: tuple[tuple[Leg, ...], ...]            # per robot, in order
    done_at_start: tuple[tuple[int, ...], ...]   # per robot: tasks whose goal is its start
    paths: tuple[tuple[int, ...], ...]           # per robot: its roadmap place at each step
    roadmap: Roadmap
    priority: tuple[int, ...]


def plan_fleet(starts_m: list[tuple[float, float]], tasks: list[list[Task]], *, seed: int = 0,
               clearance_m: float = CLEARANCE_M, attempts: int = 0) -> FleetPlan:
    """Paths and legs for every robot (``tasks[k]``: robot k's goals, in order).

    Raises
    ------
    PlanningError
        Tasks that wait for each other in a cycle, places closer than the clearance that two
        robots must hold at once, or tasks no plan on the roadmap meets.
    PlannerGaveUpError
        LaCAM searched ``LACAM_MAX_NODES`` configurations without a plan.

    ``attempts``: priority orders tried before LaCAM (default ``PRIORITY_ORDERS``, at most 4
    per robot).
    """
    _check(starts_m, tasks, clearance_m)
    points = list(starts_m) + [task.goal_m for robot in tasks for task in robot]
    roadmap = build_roadmap(points, clearance_m=clearance_m)
    order = _dependency_order(tasks)
    rng = random.Random(seed)
    for _ in range(attempts or min(4 * len(starts_m), PRIORITY_ORDERS)):
        paths, arrivals, failed = _plan_in_order(roadmap, starts_m, tasks, order)
        if failed is None:
            legs, done_at_start = action_dependencies(roadmap, paths, arrivals, tasks)
            return FleetPlan(tuple(starts_m), tuple(tuple(robot) for robot in tasks), legs,
                             done_at_start, tuple(tuple(path) for path in paths), roadmap,
                             tuple(order))
        # The robot that found no way planned earlier; if it was first already, another order.
        promoted = _respecting_waits([failed] + [robot for robot in order if robot != failed],
                                     tasks)
        if promoted is None or promoted == order:
            promoted = _respecting_waits(rng.sample(order, len(order)), tasks)
        order = promoted or order
    return _plan_by_lacam(starts_m, tasks, points, seed, clearance_m)


def _plan_by_lacam(starts_m: list[tuple[float, float]], tasks: list[list[Task]],
                   points: list[tuple[float, float]], seed: int, clearance_m: float
                   ) -> FleetPlan:
    roadmap = build_roadmap(points, clearance_m=clearance_m, lanes_m=LANES_M)
    try:
        paths, arrivals, ranks = lacam_paths(roadmap, [roadmap.place_of(s) for s in starts_m],
                                             tasks, seed=seed, max_nodes=LACAM_MAX_NODES)
    except SearchEndedError as error:
        named = '; '.join(
            f'robot {robot}\'s goal {goal} at ({tasks[robot][goal].goal_m[0] * 1e3:g}, '
            f'{tasks[robot][goal].goal_m[1] * 1e3:g}) mm' for robot, goal in error.unfinished[:3])
        if isinstance(error, NoPlanError):
            raise PlanningError(f'no plan for the tasks: {named} cannot be reached with the '
                                f'other robots where they must be ({error})') from None
        raise PlannerGaveUpError(f'the planner gave up ({error}); still to do then: '
                                 f'{named}') from None
    legs, done_at_start = action_dependencies(roadmap, paths, arrivals, tasks, ranks)
    return FleetPlan(tuple(starts_m), tuple(tuple(robot) for robot in tasks), legs,
                     done_at_start, tuple(tuple(path) for path in paths), roadmap, ())


def _check(starts_m: list[tuple[float, float]], tasks: list[list[Task]],
           clearance_m: float) -> None:
    if len(tasks) != len(starts_m):
        raise PlanningError(f'{len(starts_m)} robots but tasks for {len(tasks)}')
    for robot, start in enumerate(starts_m):
        check_on_platform(start, f'robot {robot}\'s start')
        for index, task in enumerate(tasks[robot]):
            check_on_platform(task.goal_m, f'robot {robot}\'s goal {index}')
            if task.after is not None:
                other, goal = task.after
                if not (0 <= other < len(tasks) and 0 <= goal < len(tasks[other])):
                    raise PlanningError(f'robot {robot}\'s goal {index} waits for robot '
                                        f'{other}\'s goal {goal}: there is no such goal')
    for a, b in itertools.combinations(range(len(starts_m)), 2):
        gap = math.dist(starts_m[a], starts_m[b])
        if gap < clearance_m - ROUNDING_M:
            raise PlanningError(f'robots {a} and {b} start {gap * 1e3:.2f} mm apart: centres '
                                f'must be {clearance_m * 1e3:g} mm apart (9 mm discs)')
        finals = [tasks[k][-1].goal_m if tasks[k] else starts_m[k] for k in (a, b)]
        gap = math.dist(*finals)
        if gap < clearance_m - ROUNDING_M:
            raise PlanningError(f'robots {a} and {b} would end {gap * 1e3:.2f} mm apart: '
                                f'their last goals must be {clearance_m * 1e3:g} mm apart')


def _dependency_order(tasks: list[list[Task]]) -> list[int]:
    order = _respecting_waits(list(range(len(tasks))), tasks)
    if order is None:
        waiting = sorted({k for k, robot in enumerate(tasks) for task in robot if task.after})
        raise PlanningError(f'the tasks wait for each other in a cycle ("after" of robots '
                            f'{waiting})')
    return order


def _respecting_waits(preferred: list[int], tasks: list[list[Task]]) -> list[int] | None:
    """``preferred`` reordered as little as needed so that a robot whose goal waits for
    another's comes after it (None: they wait in a cycle)."""
    needs = {robot: {task.after[0] for task in tasks[robot]
                     if task.after is not None and task.after[0] != robot}
             for robot in preferred}
    order: list[int] = []
    while len(order) < len(preferred):
        ready = [robot for robot in preferred if robot not in order and needs[robot] <= set(order)]
        if not ready:
            return None
        order.append(ready[0])
    return order


class _Reservations:
    """The segments the robots planned so far hold at each step, and where they rest after."""

    def __init__(self, roadmap: Roadmap) -> None:
        self.roadmap = roadmap
        self.by_step: list[set[int]] = []
        self.rests: list[tuple[int, int]] = []       # (stay segment, from step)
        self.last_step_near: dict[int, int] = {}     # segment -> last step something near it

    def add(self, path: list[int]) -> None:
        for step in range(len(path) - 1):
            segment = self.roadmap.segment(path[step], path[step + 1])
            while len(self.by_step) <= step:
                self.by_step.append(set())
            self.by_step[step].add(segment)
            for near in self.roadmap.conflicts[segment]:
                self.last_step_near[near] = max(self.last_step_near.get(near, -1), step)
        self.rests.append((self.roadmap.segment(path[-1], path[-1]), len(path) - 1))

    def free(self, segment: int, step: int) -> bool:
        conflicts = self.roadmap.conflicts[segment]
        if step < len(self.by_step) and self.by_step[step] & conflicts:
            return False
        return not any(rest in conflicts and step >= since for rest, since in self.rests)

    def can_rest(self, place: int, from_step: int) -> bool:
        return self.last_step_near.get(self.roadmap.segment(place, place), -1) < from_step


def _search(roadmap: Roadmap, reserved: _Reservations, start: int, start_step: int, goal: int,
            earliest: int, final: bool) -> list[int] | None:
    """Space-time A*: places from ``start`` at ``start_step`` to ``goal`` at a step no earlier
    than ``earliest`` (and, for a ``final`` goal, one it can stay at for good)."""
    remaining = distances_to(roadmap, goal)
    if start not in remaining:
        return None
    frontier = [(start_step + remaining[start], start_step, start)]
    came_from: dict[tuple[int, int], tuple[int, int] | None] = {(start, start_step): None}
    while frontier:
        _, step, place = heapq.heappop(frontier)
        if place == goal and step >= earliest and (not final or reserved.can_rest(goal, step)):
            path = [place]
            node = came_from[(place, step)]
            while node is not None:
                path.append(node[0])
                node = came_from[node]
            return path[::-1]
        if step - start_step >= MAX_STEPS:
            continue
        for near in (place, *roadmap.neighbours[place]):
            key = (near, step + 1)
            if key in came_from or near not in remaining:
                continue
            if near == goal != place and step + 1 < earliest:
                continue        # not at a goal that waits for another robot's before it is done
            if not reserved.free(roadmap.segment(place, near), step):
                continue
            came_from[key] = (place, step)
            heapq.heappush(frontier, (step + 1 + remaining[near], step + 1, near))
    return None


def _plan_in_order(roadmap: Roadmap, starts_m: list[tuple[float, float]],
                   tasks: list[list[Task]], order: list[int]
                   ) -> tuple[list[list[int]], list[list[int]], int | None]:
    """Every robot's path in ``order``; arrivals[k][i]: the step robot k reaches goal i."""
    reserved = _Reservations(roadmap)
    paths: list[list[int]] = [[] for _ in starts_m]
    arrivals: list[list[int]] = [[] for _ in starts_m]
    for robot in order:
        path = [roadmap.place_of(starts_m[robot])]
        for index, task in enumerate(tasks[robot]):
            earliest = 0
            if task.after is not None:
                earliest = arrivals[task.after[0]][task.after[1]] + 1
            piece = _search(roadmap, reserved, path[-1], len(path) - 1,
                            roadmap.place_of(task.goal_m), earliest,
                            final=index == len(tasks[robot]) - 1)
            if piece is None:
                return paths, arrivals, robot
            path.extend(piece[1:])
            # There since its last move (a wait at the goal after it counts as done).
            arrived, piece_start = len(path) - 1, len(path) - len(piece)
            while arrived > piece_start and path[arrived - 1] == path[arrived]:
                arrived -= 1
            arrivals[robot].append(arrived)
        if not tasks[robot] and not reserved.can_rest(path[0], 0):
            return paths, arrivals, robot
        reserved.add(path)
        paths[robot] = path
    return paths, arrivals, None
