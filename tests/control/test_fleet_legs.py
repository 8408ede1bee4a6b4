"""The dispatcher of a fleet's goals: each leg through points at most its controller's spacing
apart, its end to the leg's tolerance, a leg handed out only once the legs it waits for have
ended, every leg once."""

from __future__ import annotations

import math

import pytest

from omni_micro_control.fleet_legs import SUB_GOAL_SPACING_M, LegDispatcher
from omni_micro_control.fleet_plan import WAYPOINT_TOLERANCE_M, Task, plan_fleet

# Four robots on a cross, each to the opposite end: every path crosses every other's goal.
CROSS_STARTS = [(0.0, 0.0), (0.1, 0.0), (0.05, 0.05), (0.05, -0.05)]
CROSS_TASKS = [[Task((0.1, 0.0))], [Task((0.0, 0.0))], [Task((0.05, -0.05))],
               [Task((0.05, 0.05))]]


@pytest.mark.parametrize('controllers', [None, ['model', 'servo', 'paper', 'model']])
def test_every_leg_is_handed_out_once_in_order_and_only_after_what_it_waits_for(controllers):
    plan = plan_fleet(CROSS_STARTS, CROSS_TASKS)
    dispatcher = LegDispatcher(plan, controllers)
    spacings_m = [SUB_GOAL_SPACING_M[mode] for mode in controllers or ['paper'] * 4]
    given = dispatcher.startable()
    ended: set[tuple[int, int]] = set()
    legs_driven = [0] * len(CROSS_STARTS)
    waited = 0
    while given:
        order = given.pop(0)
        robot = order.robot
        leg = plan.legs[robot][legs_driven[robot]]
        assert all(need in ended for need in leg.waits_for)   # never early
        orders = [order]
        following, finished = dispatcher.reached(robot)
        while following is not None:
            orders.append(following)
            following, finished = dispatcher.reached(robot)
        assert finished == leg
        # Points on the way to 0.2 mm, the leg's end to the leg's own tolerance.
        assert [o.tolerance_m for o in orders] == [WAYPOINT_TOLERANCE_M] * (len(orders) - 1) \
            + [leg.tolerance_m]
        # The points lie on the leg, at most the robot's controller's spacing apart (the paper's
        # rule and the servo 24 mm, the model 10 mm), the last its end.
        points = [o.goal_m for o in orders]
        hops = [math.dist(a, b) for a, b in zip([leg.start_m, *points], points, strict=False)]
        assert max(hops) <= spacings_m[robot] + 1e-12
        if math.dist(leg.start_m, leg.end_m) > 24e-3:
            assert max(hops) > spacings_m[robot] / 2.0
        assert math.dist(points[-1], leg.end_m) < 1e-12
        ended.add((robot, legs_driven[robot]))
        legs_driven[robot] += 1
        newly = dispatcher.startable()
        waited += sum(bool(plan.legs[o.robot][legs_driven[o.robot]].waits_for) for o in newly)
        given += newly
    assert dispatcher.finished
    assert legs_driven == [len(legs) for legs in plan.legs]
    assert waited > 0   # the crossing made some leg wait for another robot's


def test_a_robot_already_driving_is_not_handed_another_leg():
    dispatcher = LegDispatcher(plan_fleet(CROSS_STARTS, CROSS_TASKS))
    first = dispatcher.startable()
    assert first and all(dispatcher.driving(order.robot) for order in first)
    assert dispatcher.startable() == []


def test_each_goal_counts_from_the_end_it_follows():
    """The twin and the graph's coordinator both stamp a goal so: the point before it, or the
    later of its own last leg's end and the ends its leg waits for."""
    plan = plan_fleet(CROSS_STARTS, CROSS_TASKS)
    dispatcher = LegDispatcher(plan)
    given = dispatcher.startable()
    assert {order.stamp_s for order in given} == {0.0}
    clock, ended_at, last_end, waited = 0.0, {}, [0.0] * len(CROSS_STARTS), 0
    while given:
        order = given.pop(0)
        clock += 1.5
        following, ended = dispatcher.reached(order.robot, clock)
        if following is not None:
            assert following.stamp_s == clock   # from the point before it
            given.append(following)
            continue
        assert ended is not None
        ended_at[(order.robot, ended.index)] = last_end[order.robot] = clock
        for newly in dispatcher.startable():
            leg = dispatcher.leg(newly.robot)
            assert leg is not None
            waited += bool(leg.waits_for)
            assert newly.stamp_s == max([last_end[newly.robot],
                                         *(ended_at[need] for need in leg.waits_for)])
            given.append(newly)
    assert dispatcher.finished and waited > 0
