"""LaCAM on the fleet's roadmap: complete (a plan whenever one exists, and a proof when none
does), and every step it takes keeps the robots clear of each other, moves taken in turn."""

from __future__ import annotations

import itertools
import random

import numpy as np
import pytest

from omni_micro_control.fleet_lacam import NoPlanError, SearchLimitError, lacam, lacam_paths
from omni_micro_control.fleet_plan import Task
from omni_micro_control.fleet_roadmap import CLEARANCE_M, Roadmap, build_roadmap, pair_distances


def corridor(length: int) -> Roadmap:
    """Places 12 mm apart on a line: robots can follow but never pass each other."""
    places = np.array([(0.012 * index, 0.0) for index in range(length)])
    pairs = [(u, u) for u in range(length)] + [(u, u + 1) for u in range(length - 1)]
    ends = np.array(pairs)
    conflicts = []
    for a, b in pairs:
        distances = pair_distances(
            np.repeat(places[[a]], len(pairs), 0), np.repeat(places[[b]], len(pairs), 0),
            places[ends[:, 0]], places[ends[:, 1]])
        conflicts.append(frozenset(np.flatnonzero(distances < CLEARANCE_M - 1e-9).tolist()))
    neighbours = tuple(tuple(v for v in (u - 1, u + 1) if 0 <= v < length)
                       for u in range(length))
    return Roadmap(places, neighbours, {pair: i for i, pair in enumerate(pairs)},
                   tuple(conflicts), CLEARANCE_M)


def test_two_robots_that_must_pass_each_other_in_a_corridor_have_no_plan():
    road = corridor(4)
    tasks = [[Task(tuple(road.places_m[3]))], [Task(tuple(road.places_m[0]))]]
    with pytest.raises(NoPlanError) as raised:
        lacam(road, [0, 3], tasks)
    assert {robot for robot, _ in raised.value.unfinished} <= {0, 1}


def test_robots_following_each_other_down_a_corridor_take_turns():
    # Three robots abreast of each other's places: each can only enter the place the one
    # ahead leaves, the one ahead moving first.
    road = corridor(6)
    tasks = [[Task(tuple(road.places_m[goal]))] for goal in (3, 4, 5)]
    paths, arrivals, ranks = lacam_paths(road, [0, 1, 2], tasks)
    assert [path[-1] for path in paths] == [3, 4, 5]
    followed = 0
    for step in range(len(paths[0]) - 1):
        for behind, ahead in itertools.permutations(range(3), 2):
            if paths[behind][step + 1] == paths[ahead][step] != paths[ahead][step + 1]:
                assert ranks[behind][step] > ranks[ahead][step]     # enters the place left
                followed += 1
    assert followed
    assert all(len(goals) == 1 for goals in arrivals)


def test_each_step_keeps_every_robot_clear_of_the_others_moves_taken_in_turn():
    rng = random.Random(7)
    grid = [tuple(place) for place in build_roadmap([]).places_m]
    starts, goals = rng.sample(grid, 30), rng.sample(grid, 30)
    road = build_roadmap(starts + goals, lanes_m=0.02)
    tasks = [[Task(goal)] for goal in goals]
    paths, _, ranks = lacam_paths(road, [road.place_of(s) for s in starts], tasks, seed=3)
    stays = [road.segment(p, p) for p in range(len(road.places_m))]
    for step in range(len(paths[0]) - 1):
        turns = sorted({ranks[robot].get(step, -1) for robot in range(30)} - {-1})
        for turn in turns:
            # Those moving in this turn, each against everyone else where they stand then.
            movers = [r for r in range(30) if ranks[r].get(step) == turn]
            for robot in movers:
                segment = road.segment(paths[robot][step], paths[robot][step + 1])
                for other in range(30):
                    if other == robot:
                        continue
                    if other in movers:
                        theirs = road.segment(paths[other][step], paths[other][step + 1])
                    else:
                        moved = ranks[other].get(step, -1) != -1 and ranks[other][step] < turn
                        theirs = stays[paths[other][step + 1 if moved else step]]
                    assert theirs not in road.conflicts[segment], (step, robot, other)
    assert [path[-1] for path in paths] == [road.place_of(goal) for goal in goals]


def test_the_search_stops_at_its_bound_naming_what_is_left():
    road = corridor(4)
    tasks = [[Task(tuple(road.places_m[3]))], [Task(tuple(road.places_m[0]))]]
    with pytest.raises(SearchLimitError, match='configurations') as raised:
        lacam(road, [0, 3], tasks, max_nodes=2)
    assert raised.value.unfinished
