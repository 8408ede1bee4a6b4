"""The fleet planner: every leg a straight drive between roadmap places, no two robots ever
closer than the clearance whatever each leg takes, nobody waiting for ever, goals in order."""

from __future__ import annotations

import itertools
import math
import random
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from omni_micro_common.conventions import GOAL_TOLERANCE_M
from omni_micro_control.fleet_files import fleet_from
from omni_micro_control.fleet_plan import (
    MACRO_GOAL_TOLERANCE_M,
    WAYPOINT_TOLERANCE_M,
    FleetPlan,
    PlanningError,
    Task,
    _plan_by_lacam,
    plan_fleet,
)
from omni_micro_control.fleet_roadmap import (
    CLEARANCE_M,
    RoadmapError,
    build_roadmap,
    point_segment_distance,
    segment_distances,
)

MICRO = (0.1, 0.0)
# Four robots on a cross, each to the opposite end: every path crosses every other's goal.
CROSS_STARTS = [(0.0, 0.0), (0.1, 0.0), (0.05, 0.05), (0.05, -0.05)]
CROSS_TASKS = [[Task((0.1, 0.0))], [Task((0.0, 0.0))], [Task((0.05, -0.05))],
               [Task((0.05, 0.05))]]


def execute(plan: FleetPlan, durations: random.Random) -> tuple[float, list[list[float]]]:
    """Run the legs as the platform would, each taking a random time, and return the closest
    two centres came and when each robot ended each leg. Legs start as soon as what they wait
    for has ended (an event simulation; robots drive their legs at constant speed)."""
    ended: dict[tuple[int, int], float] = {}
    ends = [[0.0] * len(legs) for legs in plan.legs]
    spans: list[list[tuple[float, float, tuple, tuple]]] = [[] for _ in plan.legs]
    pending = [(0.0, robot, 0) for robot, legs in enumerate(plan.legs) if legs]
    while pending:
        progressed = False
        for entry in list(pending):
            ready_at, robot, index = entry
            leg = plan.legs[robot][index]
            if all(need in ended for need in leg.waits_for):
                start = max([ready_at] + [ended[need] for need in leg.waits_for])
                finish = start + durations.uniform(0.1, 5.0)
                ended[(robot, index)] = finish
                ends[robot][index] = finish
                spans[robot].append((start, finish, leg.start_m, leg.end_m))
                pending.remove(entry)
                if index + 1 < len(plan.legs[robot]):
                    pending.append((finish, robot, index + 1))
                progressed = True
        assert progressed, f'the legs wait for each other: {pending}'
    return closest_approach(plan, spans), ends


def tracks(plan: FleetPlan, spans, times: np.ndarray) -> np.ndarray:
    """Every robot's centre at each of ``times`` (robots, times, 2): standing on its start, then
    driving each leg at constant speed, standing where it ended until the next starts from
    there (a robot that jumped would fail here)."""
    centres = np.empty((len(spans), len(times), 2))
    for robot, legs in enumerate(spans):
        knot_times, knots = [0.0], [plan.starts_m[robot]]
        for start, finish, leg_start, leg_end in legs:
            assert leg_start == knots[-1], f'robot {robot} jumps at {start} s'
            knot_times += [start, finish]
            knots += [leg_start, leg_end]
        xy = np.array(knots)
        centres[robot, :, 0] = np.interp(times, knot_times, xy[:, 0])
        centres[robot, :, 1] = np.interp(times, knot_times, xy[:, 1])
    return centres


def closest_approach(plan: FleetPlan, spans) -> float:
    """Exact: between two consecutive leg starts or ends every robot moves in a straight line
    at constant speed, so each pair's offset does too; its closest to zero is on that segment."""
    times = np.array(sorted({0.0} | {t for robot in spans for start, finish, *_ in robot
                                     for t in (start, finish)}))
    begins, ends = (times[:-1], times[1:]) if len(times) > 1 else (times, times)
    first, second = np.triu_indices(len(spans), 1)
    if not len(first):
        return math.inf
    at_begins, at_ends = tracks(plan, spans, begins), tracks(plan, spans, ends)
    offsets0, offsets1 = at_begins[first] - at_begins[second], at_ends[first] - at_ends[second]
    return float(np.min(point_segment_distance(np.zeros_like(offsets0), offsets0, offsets1)))


def test_segments_distances_are_those_of_geometry():
    starts = np.array([[0.0, 0.0], [0.0, 1.0], [0.5, -1.0], [3.0, 0.0], [2.0, 2.0]])
    ends = np.array([[1.0, 0.0], [1.0, 1.0], [0.5, 1.0], [3.0, 0.0], [2.0, 2.0]])
    d = segment_distances(starts, ends)
    assert d[0, 1] == pytest.approx(1.0)      # parallel lanes
    assert d[0, 2] == 0.0 and d[1, 2] == 0.0  # crossing, touching at an end
    assert d[0, 3] == pytest.approx(2.0)      # a point beyond an end
    assert d[3, 4] == pytest.approx(math.sqrt(5.0))   # two points
    assert np.allclose(d, d.T)


def test_the_micro_field_is_a_place_and_the_platform_edge_is_refused():
    roadmap = build_roadmap([(0.0123, -0.0456)])
    roadmap.place_of(MICRO)
    roadmap.place_of((0.0123, -0.0456))
    with pytest.raises(RoadmapError, match=r'robot 0\'s goal 0 \(130, 0\) mm is off the platform'):
        plan_fleet([(0.0, 0.0)], [[Task((0.13, 0.0))]])


def test_robots_crossing_each_others_goals_all_arrive_and_never_come_close():
    plan = plan_fleet(CROSS_STARTS, CROSS_TASKS)
    for robot, legs in enumerate(plan.legs):
        assert legs[0].start_m == CROSS_STARTS[robot]
        assert legs[-1].end_m == CROSS_TASKS[robot][-1].goal_m and legs[-1].tasks == (0,)
        assert all(a.end_m == b.start_m for a, b in itertools.pairwise(legs))
    # Waits point only to legs that start earlier: no cycle, whatever the durations.
    for legs in plan.legs:
        for leg in legs:
            for other, index in leg.waits_for:
                assert plan.legs[other][index].steps[0] < leg.steps[0]
    for seed in range(20):
        closest, _ = execute(plan, random.Random(seed))
        assert closest >= CLEARANCE_M - 1e-9


def test_the_execution_sees_robots_come_closer_than_the_clearance():
    """The check every plan here passes can fail: the cross's plan with its waits taken away
    has robots driving through places others still hold."""
    plan = plan_fleet(CROSS_STARTS, CROSS_TASKS)
    unwaited = replace(plan, legs=tuple(tuple(replace(leg, waits_for=()) for leg in legs)
                                        for legs in plan.legs))
    for seed in range(5):
        closest, _ = execute(unwaited, random.Random(seed))
        assert closest < CLEARANCE_M / 2


def test_the_micro_field_goal_is_reached_to_the_micro_s_tolerance_waypoints_coarser():
    plan = plan_fleet([(0.0, 0.0)], [[Task((0.03, 0.02)), Task((0.1001, 0.0002))]])
    tolerances = [leg.tolerance_m for leg in plan.legs[0]]
    tasks = [leg.tasks[0] if leg.tasks else None for leg in plan.legs[0]]
    assert tolerances[tasks.index(0)] == MACRO_GOAL_TOLERANCE_M
    assert tolerances[tasks.index(1)] == GOAL_TOLERANCE_M
    assert set(tolerances[i] for i, task in enumerate(tasks) if task is None) == {
        WAYPOINT_TOLERANCE_M}
    assert tasks.index(0) < tasks.index(1)


def test_a_goal_after_another_robot_s_is_reached_after_it_whatever_the_durations():
    # Robot 1 may bring its part to the micro field only once robot 0 has left its own there.
    tasks = [[Task(MICRO), Task((0.05, 0.04))], [Task((0.1, -0.0003), after=(0, 1))]]
    plan = plan_fleet([(0.0, 0.0), (0.05, -0.05)], tasks)
    arrive_first = next(leg for leg in plan.legs[0] if leg.tasks == (1,))
    arrive_second = next(leg for leg in plan.legs[1] if leg.tasks == (0,))
    for seed in range(10):
        closest, ends = execute(plan, random.Random(seed))
        assert closest >= CLEARANCE_M - 1e-9
        assert ends[1][arrive_second.index] > ends[0][arrive_first.index]


@pytest.mark.parametrize('starts, tasks, message', [
    ([(0.0, 0.0), (0.005, 0.0)], [[], []], 'robots 0 and 1 start 5.00 mm apart'),
    ([(0.0, 0.0), (0.05, 0.0)], [[Task(MICRO)], [Task((0.1, 0.004))]],
     'robots 0 and 1 would end 4.00 mm apart'),
    ([(0.0, 0.0), (0.05, 0.0)], [[Task(MICRO, after=(1, 0))], [Task((0.0, 0.03), after=(0, 0))]],
     'the tasks wait for each other in a cycle'),
    ([(0.0, 0.0)], [[Task(MICRO, after=(3, 0))]], "waits for robot 3's goal 0: there is no"),
])
def test_tasks_no_plan_can_meet_are_named(starts, tasks, message):
    with pytest.raises(PlanningError, match=message):
        plan_fleet(starts, tasks)


def spread(draw, count: int) -> list[tuple[float, float]]:
    """``count`` places on a 20 mm lattice of the platform, all different."""
    cells = draw(st.lists(st.tuples(st.integers(-1, 6), st.integers(-3, 3)), min_size=count,
                          max_size=count, unique=True))
    return [(0.0 + 0.02 * i, 0.02 * j) for i, j in cells]


@st.composite
def fleets(draw):
    count = draw(st.integers(2, 5))
    starts = spread(draw, count)
    goals = spread(draw, count)
    return starts, [[Task(goal)] for goal in goals], draw(st.integers(0, 1000))


@settings(max_examples=30, deadline=None)
@given(fleets())
def test_any_fleet_keeps_its_clearance_whatever_each_leg_takes(fleet):
    starts, tasks, seed = fleet
    plan = plan_fleet(starts, tasks)
    closest, _ = execute(plan, random.Random(seed))
    assert closest >= CLEARANCE_M - 1e-9
    for robot, legs in enumerate(plan.legs):
        end = legs[-1].end_m if legs else starts[robot]
        assert end == tasks[robot][0].goal_m


def test_the_plan_is_the_same_for_the_same_tasks():
    first = plan_fleet(CROSS_STARTS, CROSS_TASKS)
    assert plan_fleet(CROSS_STARTS, CROSS_TASKS).legs == first.legs


def test_a_robot_walled_in_by_those_planned_before_it_is_planned_first():
    # Robots 0 and 1 end beside the platform's corner, robot 2 in it: planned in index order,
    # 0 and 1 would rest across its only ways in.
    starts = [(0.016, -0.06), (-0.02, -0.024), (0.1, 0.06)]
    tasks = [[Task((-0.008, -0.06))], [Task((-0.02, -0.048))], [Task((-0.02, -0.06))]]
    plan = plan_fleet(starts, tasks)
    assert plan.priority[0] == 2
    for seed in range(5):
        closest, _ = execute(plan, random.Random(seed))
        assert closest >= CLEARANCE_M - 1e-9
    assert [legs[-1].end_m for legs in plan.legs] == [robot[0].goal_m for robot in tasks]


def assert_carried_out(plan: FleetPlan, tasks, seeds=range(3)) -> list[list[list[float]]]:
    """Whatever each leg takes, the centres keep the clearance, and every robot ends on its
    last goal (or its start). Returns each seed's leg ends (execute's)."""
    ends_by_seed = []
    for seed in seeds:
        closest, ends = execute(plan, random.Random(seed))
        assert closest >= CLEARANCE_M - 1e-9
        ends_by_seed.append(ends)
    for robot, legs in enumerate(plan.legs):
        end = legs[-1].end_m if legs else plan.starts_m[robot]
        assert end == (tasks[robot][-1].goal_m if tasks[robot] else plan.starts_m[robot])
    return ends_by_seed


def test_tasks_no_priority_order_can_plan_are_planned_by_lacam():
    # Drawn, 3 robots, seed 3: robot 1 starts between 0 and 2, and whichever goes first, the
    # others' paths pass where a robot planned later still stands.
    fleet = fleet_from('3', None, 1, 3)
    plan = plan_fleet(fleet.starts_m, fleet.tasks, seed=3)
    assert plan.priority == ()           # LaCAM's: no order of priorities
    assert_carried_out(plan, fleet.tasks)


@pytest.mark.parametrize('robots, seed', [(16, 0), (32, 1), (42, 2)])
def test_a_drawn_fleet_of_up_to_42_robots_is_planned_and_keeps_its_clearance(robots, seed):
    fleet = fleet_from(str(robots), None, 1, seed)
    plan = plan_fleet(fleet.starts_m, fleet.tasks, seed=seed)
    assert_carried_out(plan, fleet.tasks, seeds=range(2))
    # No two robots end on the same place (42 robots: goals beyond the lattice too).
    ends = [robot[-1].goal_m for robot in fleet.tasks]
    assert len(set(ends)) == robots


def test_waits_between_goals_hold_in_a_lacam_plan():
    # Robot 1 may come to its goal only after robot 0 has reached the micro field, with robot
    # 2 starting between them (prioritized planning finds no order: LaCAM plans it).
    starts = [(-0.02, -0.06), (-0.02, -0.04), (-0.02, -0.02)]
    tasks = [[Task(MICRO)], [Task((0.0, 0.04), after=(0, 0))], [Task((0.06, -0.04))]]
    plan = plan_fleet(starts, tasks, seed=0, attempts=1)
    assert plan.priority == ()
    assert_carried_out(plan, tasks)
    for seed in range(5):
        _, ends = execute(plan, random.Random(seed))
        first = next(leg for leg in plan.legs[0] if 0 in leg.tasks)
        second = next(leg for leg in plan.legs[1] if 0 in leg.tasks)
        assert ends[1][second.index] > ends[0][first.index]


@st.composite
def waiting_fleets(draw):
    """2-5 robots of one or two goals each on the lattice, any goal waiting for a goal of a
    robot listed before (so no cycle)."""
    count = draw(st.integers(2, 5))
    starts = spread(draw, count)
    places = spread(draw, 2 * count)
    tasks: list[list[Task]] = []
    earlier: list[tuple[int, int]] = []
    for robot in range(count):
        goals = draw(st.integers(1, 2))
        tasks.append([Task(places[2 * robot + index],
                           after=draw(st.sampled_from([None, *earlier])) if earlier else None)
                      for index in range(goals)])
        earlier += [(robot, index) for index in range(goals)]
    return starts, tasks, draw(st.integers(0, 1000))


@settings(max_examples=40, deadline=None)
@given(waiting_fleets())
def test_lacam_keeps_the_clearance_and_every_wait_whatever_each_leg_takes(fleet):
    """LaCAM's plan (the planner's second way, taken here first) of tasks that wait for others:
    whatever each leg takes, no two centres closer than the clearance, nobody waiting in a cycle
    (execute asserts it), every robot on its last goal, and each goal reached after the one it
    waits for."""
    starts, tasks, seed = fleet
    points = list(starts) + [task.goal_m for robot in tasks for task in robot]
    plan = _plan_by_lacam(starts, tasks, points, seed, CLEARANCE_M)
    runs = assert_carried_out(plan, tasks, seeds=range(seed, seed + 3))
    reached_by = {(robot, task): leg.index for robot, legs in enumerate(plan.legs)
                  for leg in legs for task in leg.tasks}
    for ends in runs:
        for robot, goals in enumerate(tasks):
            for index, task in enumerate(goals):
                if task.after is not None and {(robot, index), task.after} <= set(reached_by):
                    other, goal = task.after
                    assert (ends[robot][reached_by[robot, index]]
                            > ends[other][reached_by[other, goal]])
