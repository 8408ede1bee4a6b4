"""The fleet's twin: robots crossing each other's goals all arrive and never touch, a
goal that waits for another robot's is reached after it, a contact is a fault naming both."""

from __future__ import annotations

import math

import pytest

from omni_micro_control.fleet_files import drawn_offsets, robot_parameters
from omni_micro_control.fleet_plan import Task, plan_fleet
from omni_micro_control.fleet_roadmap import CLEARANCE_M, ROBOT_DIAMETER_M
from omni_micro_studies.fleet_twin import CONTACT, DONE, run_fleet

CROSS_STARTS = [(0.0, 0.0), (0.1, 0.0), (0.05, 0.05), (0.05, -0.05)]
CROSS_TASKS = [[Task((0.1, 0.0))], [Task((0.0, 0.0))], [Task((0.05, -0.05))],
               [Task((0.05, 0.05))]]


def offset_robots(count: int, seed: int):
    import random

    rng = random.Random(seed)
    return [robot_parameters(drawn_offsets(rng)) for _ in range(count)]


@pytest.fixture(scope='module')
def crossing():
    plan = plan_fleet(CROSS_STARTS, CROSS_TASKS)
    return plan, run_fleet(plan, robots=offset_robots(4, 7), seed=7)


def test_robots_crossing_each_others_goals_all_arrive_without_touching(crossing):
    _, result = crossing
    assert result.outcome == DONE, result.reason
    assert result.tasks_done == 4
    for robot, run in enumerate(result.robots):
        goal = CROSS_TASKS[robot][0]
        final = run.final_state
        # Each where it was sent, to its goal's tolerance (the macro's 50 um; the micro field's
        # 3 um for the robot that ends in it).
        assert math.dist((final.x_m, final.y_m), goal.goal_m) <= goal.tolerance()
        assert run.deviations_m[0] <= goal.tolerance()
        # Each kept to its legs as the clearance counts on (half the margin each).
        assert run.off_leg_m < (CLEARANCE_M - ROBOT_DIAMETER_M) / 2.0
    assert result.closest_gap_m > ROBOT_DIAMETER_M
    assert result.closest_gap_m >= CLEARANCE_M - 2 * max(r.off_leg_m for r in result.robots)


def test_the_same_seed_gives_the_same_run(crossing):
    plan, result = crossing
    again = run_fleet(plan, robots=offset_robots(4, 7), seed=7)
    assert [r.final_state for r in again.robots] == [r.final_state for r in result.robots]
    assert again.sim_time_s == result.sim_time_s


def test_a_goal_after_another_robot_s_is_reached_after_it():
    tasks = [[Task((0.1, 0.0002)), Task((0.04, 0.04))], [Task((0.1, -0.0003), after=(0, 1))]]
    plan = plan_fleet([(0.0, 0.0), (0.04, -0.04)], tasks)
    result = run_fleet(plan, robots=offset_robots(2, 3), seed=3)
    assert result.outcome == DONE, result.reason
    first, second = result.robots
    assert second.tasks_done_s[0] > first.tasks_done_s[1]
    # Both micro-field goals to the micro camera's 3 um.
    assert first.deviations_m[0] <= 3e-6 and second.deviations_m[0] <= 3e-6


def test_robots_that_touch_end_the_run_as_a_fault_naming_both():
    # A plan that keeps centres only 5 mm apart: robot 1 drives past robot 0 7 mm away.
    plan = plan_fleet([(0.052, 0.007), (0.004, 0.0)], [[], [Task((0.1, 0.0))]],
                      clearance_m=5e-3)
    result = run_fleet(plan, robots=offset_robots(2, 1), seed=1)
    assert result.outcome == CONTACT
    assert result.reason.startswith('robots 0 and 1 touched at ')
    assert result.closest_gap_m < ROBOT_DIAMETER_M and result.closest_pair == (0, 1)


# Each robot's true offsets, wheel 1's 0 (the reference the controllers' xi2, xi3 are from).
MIXED_OFFSETS_DEG = [(0.0, 3.0, 2.0), (0.0, -2.0, 1.5), (0.0, 1.0, -1.0)]
MIXED_CONTROLLERS = ['model', 'servo', 'paper']


@pytest.fixture(scope='module')
def mixed():
    """Three robots, each its own controller, each through the micro field (3 um) and on to a
    place of its own (50 um): tolerances set per goal, goal after goal."""
    starts = [(0.04, 0.0), (0.04, 0.04), (0.04, -0.04)]
    tasks = [[Task((0.1, 0.0003)), Task((0.06, 0.02))],
             [Task((0.1, -0.0002), after=(0, 0)), Task((0.06, 0.05))],
             [Task((0.1, 0.0001), after=(1, 0)), Task((0.06, -0.05))]]
    plan = plan_fleet(starts, tasks)
    robots = [robot_parameters(offsets) for offsets in MIXED_OFFSETS_DEG]
    return tasks, plan, run_fleet(plan, robots=robots, seed=11, controllers=MIXED_CONTROLLERS)


def test_each_robot_its_own_controller_every_goal_reached_to_its_tolerance(mixed):
    tasks, plan, result = mixed
    assert result.outcome == DONE, result.reason
    assert result.closest_gap_m > ROBOT_DIAMETER_M
    for robot, run in enumerate(result.robots):
        assert len(run.tasks_done_s) == len(tasks[robot])
        for task, deviation in zip(tasks[robot], run.deviations_m, strict=True):
            assert deviation <= task.tolerance(), (robot, task, deviation)
        assert run.off_leg_m < (CLEARANCE_M - ROBOT_DIAMETER_M) / 2.0
        assert run.moves >= len(plan.legs[robot])   # each leg a move from rest at least


def test_the_model_and_the_servo_learn_their_own_robot_the_paper_s_rule_nothing(mixed):
    _, _, result = mixed
    for run, offsets, mode in zip(result.robots, MIXED_OFFSETS_DEG, MIXED_CONTROLLERS,
                                  strict=True):
        if mode == 'paper':
            assert run.learnt_offsets_rad is None
            continue
        assert run.learnt_offsets_rad is not None
        learnt = [math.degrees(value) for value in run.learnt_offsets_rad]
        # Nearer its own robot's offsets than to any other robot's: learnt per robot.
        errors = [math.dist(learnt, other[1:]) for other in MIXED_OFFSETS_DEG]
        assert errors.index(min(errors)) == MIXED_OFFSETS_DEG.index(offsets), (mode, learnt)
        # Measured 0.03 deg off (model) and 0.15 deg (servo: its filter, from the captures of
        # two legs rolled); the other robots' are 1.5 deg and more away.
        assert errors[MIXED_OFFSETS_DEG.index(offsets)] < 0.25, (mode, learnt)


def test_an_open_loop_robot_drives_each_leg_in_one_move_and_strays_as_feedback_would_not():
    """Beside a robot of the paper's rule, the same robot (wheel offsets 0, 3, 2 deg) driven
    open loop: one move per leg, each aimed from where the camera last saw it, so its goal is
    missed by its drift and it strays off its lane past the clearance the planner left."""
    starts = [(0.0, 0.0), (0.0, 0.04)]
    tasks = [[Task((0.06, 0.0))], [Task((0.06, 0.04))]]
    plan = plan_fleet(starts, tasks)
    robots = [robot_parameters((0.0, 3.0, 2.0))] * 2
    result = run_fleet(plan, robots=robots, seed=3, controllers=['open-loop', 'paper'])
    assert result.outcome == DONE, result.reason
    open_loop, closed_loop = result.robots
    assert open_loop.moves == len(plan.legs[0]) < closed_loop.moves
    # Measured: 0.23 mm from its goal and 4.4 mm off its lane; the paper's rule 8 um, 0.25 mm.
    assert open_loop.deviations_m[0] > 4 * tasks[0][0].tolerance() >= \
        4 * closed_loop.deviations_m[0]
    assert open_loop.off_leg_m > (CLEARANCE_M - ROBOT_DIAMETER_M) / 2.0 > closed_loop.off_leg_m
