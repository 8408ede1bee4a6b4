"""LaCAM over the fleet's roadmap: a plan for any number of robots that does not give up.

LaCAM (Okumura, "LaCAM: Search-based algorithm for quick multi-agent pathfinding", AAAI 2023)
searches configurations (every robot's place at once) depth first. Each configuration is
expanded lazily: a greedy one-step generator in the manner of PIBT (Okumura et al., AIJ 2022)
proposes the next configuration, each robot in turn of priority taking the free place nearest
its goal; when that leads nowhere new, the search constrains the generator, robot by robot, to
every other choice in breadth-first order. Since every successor of a configuration is reached
by some constraint and configurations are never expanded twice, the search is complete on the
roadmap: it finds a plan whenever one exists and says so when none does.

A step here is the fleet planner's synchronous step: each robot stays or moves to a linked
place. A robot may enter a place another leaves in the same step, the other moving first:
each step carries its moves' turns, and run turn by turn no move comes within the clearance of
a robot standing still (:mod:`omni_micro_control.fleet_pibt`). A robot's goals come in order:
its goal index moves on when it stands at the goal (one that waits for another's: when it has
just come onto it, that goal done a step earlier), and the search ends when every robot has
done its last and stands on it (a robot without goals, back at its start).
"""

from __future__ import annotations

import random
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

from omni_micro_control.fleet_pibt import PibtStep
from omni_micro_control.fleet_roadmap import Roadmap, distances_to

# Constraints the search may try per configuration it keeps, on average, before it stops.
_EXPANSIONS_PER_NODE = 20
# The distance of a place from which a goal cannot be reached (no roadmap place is this far).
_UNREACHABLE = 1 << 20


class _Task(Protocol):
    """What the search needs of a goal (:class:`omni_micro_control.fleet_plan.Task`)."""

    @property
    def goal_m(self) -> tuple[float, float]: ...

    @property
    def after(self) -> tuple[int, int] | None: ...


@dataclass
class _Constraint:
    """The first ``depth`` robots of a node's order held to the places ``places``."""

    who: tuple[int, ...]
    places: tuple[int, ...]


@dataclass
class _Node:
    config: tuple[int, ...]
    done: tuple[int, ...]            # per robot: how many of its goals it has done
    parent: _Node | None
    order: tuple[int, ...]           # robots by priority, most urgent first
    priorities: tuple[float, ...]
    tree: deque[_Constraint] = field(default_factory=deque)
    ranks: dict[int, int] = field(default_factory=dict)   # robot -> its turn in the step here


class SearchEndedError(Exception):
    """The search ended without a plan; ``unfinished``: the (robot, goal index) pairs not done
    in the configuration that came closest."""

    def __init__(self, message: str, unfinished: list[tuple[int, int]]) -> None:
        super().__init__(message)
        self.unfinished = unfinished


class NoPlanError(SearchEndedError):
    """Every configuration reachable from the starts was searched: none ends the tasks."""


class SearchLimitError(SearchEndedError):
    """More configurations than the search may expand, none of them the end."""


def lacam(roadmap: Roadmap, starts: list[int], tasks: Sequence[Sequence[_Task]], *,
          seed: int = 0, max_nodes: int = 200_000) -> list[_Node]:
    """The configurations from the starts to every robot on its last goal (roadmap places; a
    robot without goals back at its start), each with the goals done there and the turns of
    the moves that led to it (robot -> its turn: a robot entering a place another leaves moves
    after it).

    Raises
    ------
    NoPlanError
        No sequence of steps on the roadmap meets the tasks.
    SearchLimitError
        ``max_nodes`` configurations expanded without an end.
    """
    search = _Search(roadmap, starts, tasks, seed)
    start = tuple(starts)
    done = search.advance(start, tuple(0 for _ in starts), None)
    priorities = tuple(search.distance(robot, start[robot], done[robot]) / 1e3
                       for robot in range(len(starts)))
    first = search.node(start, done, None, priorities)
    open_nodes = [first]
    explored = {(start, done): first}
    closest = (search.remaining(first), first)
    expansions = 0
    while open_nodes:
        expansions += 1
        if expansions > _EXPANSIONS_PER_NODE * max_nodes:
            raise SearchLimitError(f'{expansions} constraints tried on {len(explored)} '
                                   'configurations', search.unfinished(closest[1]))
        node = open_nodes[-1]
        if search.finished(node):
            return _lineage(node)
        if not node.tree:
            open_nodes.pop()
            continue
        constraint = node.tree.popleft()
        depth = len(constraint.who)
        if depth < len(starts):
            robot = node.order[depth]
            choices = [node.config[robot], *roadmap.neighbours[node.config[robot]]]
            search.rng.shuffle(choices)
            for place in choices:
                node.tree.append(_Constraint((*constraint.who, robot),
                                             (*constraint.places, place)))
        step = search.next_config(node, constraint)
        if step is None:
            continue
        config = step.configuration()
        done = search.advance(config, node.done, node.config)
        known = explored.get((config, done))
        if known is not None:
            continue
        if len(explored) >= max_nodes:
            raise SearchLimitError(f'{max_nodes} configurations searched',
                                   search.unfinished(closest[1]))
        child = search.node(config, done, node, search.next_priorities(node, config, done))
        child.ranks = step.ranks()
        explored[(config, done)] = child
        open_nodes.append(child)
        closest = min(closest, (search.remaining(child), child), key=lambda pair: pair[0])
    raise NoPlanError(f'all {len(explored)} configurations reachable from the starts searched',
                      search.unfinished(closest[1]))


def _lineage(node: _Node | None) -> list[_Node]:
    nodes = []
    while node is not None:
        nodes.append(node)
        node = node.parent
    return nodes[::-1]


def lacam_paths(roadmap: Roadmap, starts: list[int], tasks: Sequence[Sequence[_Task]], *,
                seed: int = 0, max_nodes: int = 200_000
                ) -> tuple[list[list[int]], list[list[int]], list[dict[int, int]]]:
    """:func:`lacam`'s plan as the fleet planner's: each robot's place at each step, the step
    it reaches each goal (there since its last move, or, for a goal that waits for another's,
    since it came onto it) and its turn among each step's moves (step -> turn)."""
    nodes = lacam(roadmap, starts, tasks, seed=seed, max_nodes=max_nodes)
    paths = [[node.config[robot] for node in nodes] for robot in range(len(starts))]
    ranks: list[dict[int, int]] = [{} for _ in starts]
    for step, node in enumerate(nodes[1:]):
        for robot, turn in node.ranks.items():
            ranks[robot][step] = turn
    arrivals: list[list[int]] = [[] for _ in starts]
    for step, node in enumerate(nodes):
        for robot in range(len(starts)):
            while len(arrivals[robot]) < node.done[robot]:
                index, arrived = len(arrivals[robot]), step
                floor = arrivals[robot][-1] if arrivals[robot] else 0
                if tasks[robot][index].after is None:
                    while arrived > floor and paths[robot][arrived - 1] == paths[robot][arrived]:
                        arrived -= 1
                arrivals[robot].append(arrived)
    return paths, arrivals, ranks


class _Search:
    def __init__(self, roadmap: Roadmap, starts: list[int], tasks: Sequence[Sequence[_Task]],
                 seed: int) -> None:
        self.roadmap = roadmap
        self.tasks = tasks
        self.rng = random.Random(seed)
        self.goals = [[roadmap.place_of(task.goal_m) for task in robot] for robot in tasks]
        # Where each robot ends: its last goal, or where it started.
        self.ends = [goals[-1] if goals else start
                     for goals, start in zip(self.goals, starts, strict=True)]
        self.to_goal = {place: distances_to(roadmap, place)
                        for place in {*self.ends, *(p for goals in self.goals for p in goals)}}
        self.stays = [roadmap.segment(place, place) for place in range(len(roadmap.places_m))]
        # Robots whose last goal another's waits for: once it is done they stay on it.
        self.awaited_last = {task.after for robot in tasks for task in robot
                             if task.after is not None
                             and task.after[1] == len(tasks[task.after[0]]) - 1}

    def node(self, config: tuple[int, ...], done: tuple[int, ...], parent: _Node | None,
             priorities: tuple[float, ...]) -> _Node:
        order = tuple(sorted(range(len(config)), key=lambda robot: -priorities[robot]))
        return _Node(config, done, parent, order, priorities, deque([_Constraint((), ())]))

    def distance(self, robot: int, place: int, done: int) -> int:
        goals = self.goals[robot]
        target = goals[done] if done < len(goals) else self.ends[robot]
        return self.to_goal[target].get(place, _UNREACHABLE)

    def finished(self, node: _Node) -> bool:
        return all(node.done[robot] == len(goals) and node.config[robot] == self.ends[robot]
                   for robot, goals in enumerate(self.goals))

    def remaining(self, node: _Node) -> int:
        """Steps still to go, summed over the robots (0: finished), goals not done counted."""
        return sum(self.distance(robot, node.config[robot], node.done[robot])
                   + len(self.goals[robot]) - node.done[robot]
                   for robot in range(len(node.config)))

    def unfinished(self, node: _Node) -> list[tuple[int, int]]:
        return [(robot, min(node.done[robot], len(goals) - 1))
                for robot, goals in enumerate(self.goals)
                if goals and (node.done[robot] < len(goals)
                              or node.config[robot] != self.ends[robot])]

    def advance(self, config: tuple[int, ...], done: tuple[int, ...],
                before: tuple[int, ...] | None) -> tuple[int, ...]:
        """Goals done once the robots stand at ``config``, coming from ``before`` with
        ``done``: a goal counts when its robot stands on it, one with ``after`` only when it
        has just come onto it with the goal it waits for done by then (its arrival is then the
        step it came, later than the other's)."""
        advanced = list(done)
        for robot, goals in enumerate(self.goals):
            while advanced[robot] < len(goals) and config[robot] == goals[advanced[robot]]:
                after = self.tasks[robot][advanced[robot]].after
                if after is not None and (done[after[0]] <= after[1] or before is None
                                          or before[robot] == config[robot]):
                    break
                advanced[robot] += 1
        return tuple(advanced)

    def next_priorities(self, node: _Node, config: tuple[int, ...],
                        done: tuple[int, ...]) -> tuple[float, ...]:
        """PIBT's: a robot's urgency grows each step it is not on its goal, and is its
        distance's fraction when it is."""
        priorities = []
        for robot, place in enumerate(config):
            at_goal = self.distance(robot, place, done[robot]) == 0
            fraction = node.priorities[robot] % 1.0
            priorities.append(fraction if at_goal else node.priorities[robot] + 1.0)
        return tuple(priorities)

    def next_config(self, node: _Node, constraint: _Constraint) -> PibtStep | None:
        """The step PIBT proposes under ``constraint`` (None: none keeps the robots clear)."""
        step = PibtStep(self, node.config, node.done)
        for robot, place in zip(constraint.who, constraint.places, strict=True):
            edges = step.fits(robot, place, in_progress=())
            if edges is None:
                return None
            step.assign(robot, place, edges)
        for robot in node.order:
            if step.chosen[robot] is None:
                step.pibt(robot)
        return None if step.failed else step

    def done_for_good(self, robot: int, done: int) -> bool:
        goals = self.goals[robot]
        return bool(goals) and done == len(goals) and (robot, len(goals) - 1) in self.awaited_last
