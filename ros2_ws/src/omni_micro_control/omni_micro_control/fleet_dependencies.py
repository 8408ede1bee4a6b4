"""The action dependency graph (Hönig et al., "Persistent and robust execution of MAPF
schedules in warehouses", RA-L 2019): a plan's synchronous steps turned into *legs*, straight
drives that start only once every earlier step of another robot passing within the clearance
of theirs has ended. Whatever each leg then takes, two robots are never on conflicting segments
at once, and since every leg waits only for legs that start earlier, nobody waits in a cycle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from omni_micro_control.fleet_roadmap import Roadmap

# A leg's end that is not a task's goal is reached this close (the macro camera's captures
# scatter by 26 um at 95 %); the roadmap's clearance counts it.
WAYPOINT_TOLERANCE_M = 0.2e-3


class _Task(Protocol):
    """What the legs need of a goal (:class:`omni_micro_control.fleet_plan.Task`)."""

    @property
    def after(self) -> tuple[int, int] | None: ...

    def tolerance(self) -> float: ...


@dataclass(frozen=True)
class Leg:
    """One straight drive of one robot, and what must have ended before it starts."""

    robot: int
    index: int
    start_m: tuple[float, float]
    end_m: tuple[float, float]
    steps: tuple[int, int]                       # the first and last planned step it covers
    waits_for: tuple[tuple[int, int], ...]       # (robot, leg index) that must have ended
    tasks: tuple[int, ...]                       # the tasks it completes (ends at their goal)
    tolerance_m: float


def action_dependencies(roadmap: Roadmap, paths: list[list[int]], arrivals: list[list[int]],
                        tasks: Sequence[Sequence[_Task]],
                        ranks: Sequence[dict[int, int]] | None = None
                        ) -> tuple[tuple[tuple[Leg, ...], ...], tuple[tuple[int, ...], ...]]:
    """Straight legs from the paths' moves, each waiting for the legs of other robots that hold
    a conflicting segment earlier (the action dependency graph), and for the leg that completes
    a goal its own waits for. ``ranks[k][step]``: robot k's turn among the moves of a step
    (none: the step's moves keep clear of each other, all at once)."""
    moves = [[(step, path[step], path[step + 1]) for step in range(len(path) - 1)
              if path[step] != path[step + 1]] for path in paths]
    # The move that ends at each robot's arrival step (None: the goal was its start).
    arriving = [{arrival: next((i for i, move in enumerate(own) if move[0] == arrival - 1),
                               None) for arrival in robot_arrivals}
                for own, robot_arrivals in zip(moves, arrivals, strict=True)]
    # When each move comes: its step, then its turn among the step's moves (a robot entering
    # a place another leaves that step moves after it).
    keys = [[(step, ranks[robot].get(step, 0) if ranks else 0) for step, _, _ in own]
            for robot, own in enumerate(moves)]
    by_segment: dict[int, list[tuple[int, int]]] = {}      # segment -> (robot, move index)
    for robot, own in enumerate(moves):
        for index, (_, u, v) in enumerate(own):
            by_segment.setdefault(roadmap.segment(u, v), []).append((robot, index))
    # [robot][move] -> [(other robot, its last earlier conflicting move, that move's key)]
    waits: list[list[list[tuple[int, int, tuple[int, int]]]]] = []
    for robot, own in enumerate(moves):
        waits.append([])
        for index, (step, u, v) in enumerate(own):
            key = keys[robot][index]
            latest: dict[int, int] = {}
            for segment in roadmap.conflicts[roadmap.segment(u, v)]:
                for other, their in by_segment.get(segment, ()):
                    if other != robot and keys[other][their] < key and their > latest.get(
                            other, -1):
                        latest[other] = their
            needed = [(other, their, keys[other][their]) for other, their in latest.items()]
            for goal_index, task in enumerate(tasks[robot]):
                if task.after is not None and arrivals[robot][goal_index] == step + 1:
                    other, goal = task.after
                    move = arriving[other][arrivals[other][goal]]
                    if move is not None:
                        needed.append((other, move, keys[other][move]))
            waits[robot].append(needed)
    goal_steps: list[dict[int, tuple[int, ...]]] = []
    for robot_arrivals in arrivals:
        by_step: dict[int, tuple[int, ...]] = {}
        for index, step in enumerate(robot_arrivals):
            by_step[step] = (*by_step.get(step, ()), index)
        goal_steps.append(by_step)
    leg_of: list[list[int]] = [[0] * len(own) for own in moves]
    spans: list[list[list[int]]] = []
    for robot, own in enumerate(moves):
        spans.append([])
        for index in range(len(own)):
            if spans[robot] and _extends(roadmap, own, keys[robot], spans[robot][-1], index,
                                         waits[robot], goal_steps[robot]):
                spans[robot][-1].append(index)
            else:
                spans[robot].append([index])
            leg_of[robot][index] = len(spans[robot]) - 1
    legs = []
    for robot, own in enumerate(moves):
        robot_legs = []
        for leg_index, span in enumerate(spans[robot]):
            first_step, start, _ = own[span[0]]
            last_step, _, end = own[span[-1]]
            leg_waits = sorted({(other, leg_of[other][move]) for index in span
                                for other, move, _ in waits[robot][index]})
            reached = goal_steps[robot].get(last_step + 1, ())
            tolerance = min((tasks[robot][task].tolerance() for task in reached),
                            default=WAYPOINT_TOLERANCE_M)
            robot_legs.append(Leg(robot, leg_index, _point(roadmap, start),
                                  _point(roadmap, end), (first_step, last_step), tuple(leg_waits),
                                  reached, tolerance))
        legs.append(tuple(robot_legs))
    done_at_start = tuple(goal_steps[robot].get(0, ()) for robot in range(len(paths)))
    return tuple(legs), done_at_start


def _extends(roadmap: Roadmap, own: list[tuple[int, int, int]], keys: list[tuple[int, int]],
             span: list[int], index: int, waits: list[list[tuple[int, int, tuple[int, int]]]],
             goal_steps: dict[int, tuple[int, ...]]) -> bool:
    """Whether move ``index`` may join the leg ``span``: straight on, right after it, not past
    a goal, and waiting for nothing that comes after the leg's start (no cycle of waits)."""
    last_step, last_from, last_to = own[span[-1]]
    step, start, end = own[index]
    if step != last_step + 1 or start != last_to or last_step + 1 in goal_steps:
        return False
    before = roadmap.places_m[last_to] - roadmap.places_m[last_from]
    after = roadmap.places_m[end] - roadmap.places_m[start]
    if abs(before[0] * after[1] - before[1] * after[0]) > 1e-12 or before @ after <= 0.0:
        return False
    first = keys[span[0]]
    return all(their < first for _, _, their in waits[index])


def _point(roadmap: Roadmap, place: int) -> tuple[float, float]:
    x, y = roadmap.places_m[place]
    return float(x), float(y)
