"""Which goal each robot of a fleet is given next, as goals are reached: the plan's legs in order,
each driven through points at most ``SUB_GOAL_SPACING_M`` apart (by the robot's controller), a
leg started only once the legs it waits for have ended (the action dependency graph of
:mod:`omni_micro_control.fleet_plan`).

Plain Python, shared by the fleet twin (one process) and the fleet graph's coordinator (goals
on each robot's ``/robot_k/goal_pose``), so that both hand out the same goals in the same order.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from omni_micro_control.feedback import Outcome
from omni_micro_control.fleet_files import OPEN_LOOP
from omni_micro_control.fleet_plan import WAYPOINT_TOLERANCE_M, FleetPlan, Leg

# A long leg is driven through points at most this far apart, by the robot's controller: a wheel
# offset turns each move a little, and the planner's clearance leaves each robot 1.5 mm off its
# legs (omni_micro_control.fleet_roadmap). The paper's rule, sent 140 mm at once, strayed
# 1.61 mm (8 robots, offsets up to 3 deg); 24 mm apart, 0.44 mm (20 crossing runs). The model
# mode shoots one arc to each point, through offsets it has not learnt yet on the first legs:
# 24 mm apart it strayed 2.02 mm, 12 mm 1.30 mm, 10 mm 0.43 mm. The servo corrects while it
# rolls: 24 mm apart, 0.49 mm. Open loop drives each leg in one move: points on the way would
# each be aimed at from where the camera sees it, which is feedback.
SUB_GOAL_SPACING_M = {'paper': 24e-3, 'model': 10e-3, 'servo': 24e-3, OPEN_LOOP: math.inf}
# The ends of a goal after which a robot goes on to its next: reached, or its open-loop move
# done (wherever that left it). Any other end is the robot's fault and ends the run.
LEG_ENDS = (Outcome.REACHED, Outcome.COMPLETED)


@dataclass(frozen=True)
class GoalOrder:
    """Robot ``robot`` is to go to ``goal_m``, reached within ``tolerance_m``, counting from
    ``stamp_s``: the end it follows (the point before it, or the later of the legs' ends its leg
    waits for), so that the goal starts from the same simulated time however late it is handed
    out."""

    robot: int
    goal_m: tuple[float, float]
    tolerance_m: float
    stamp_s: float = 0.0


@dataclass
class _Progress:
    legs: tuple[Leg, ...]
    legs_done: int = 0
    points: list[tuple[float, float]] = field(default_factory=list)   # of the leg under way
    driving: bool = False
    ended_s: list[float] = field(default_factory=list)   # when each leg driven ended

    @property
    def leg(self) -> Leg | None:
        return self.legs[self.legs_done] if self.legs_done < len(self.legs) else None


class LegDispatcher:
    """Hands out each robot's goals for ``plan``: :meth:`startable` at the start and after each
    leg's end, :meth:`reached` as a robot reaches the goal it was given."""

    def __init__(self, plan: FleetPlan, controllers: Sequence[str] | None = None) -> None:
        """``controllers``: each robot's controller mode (the paper's rule by default), which
        sets how far apart the points of its legs are (``SUB_GOAL_SPACING_M``)."""
        self.robots = [_Progress(legs) for legs in plan.legs]
        self.spacings_m = [SUB_GOAL_SPACING_M[mode] for mode in
                           (controllers or ['paper'] * len(self.robots))]

    def legs_done(self, robot: int) -> int:
        return self.robots[robot].legs_done

    def leg(self, robot: int) -> Leg | None:
        """The leg robot ``robot`` drives, or drives next (None: it has driven them all)."""
        return self.robots[robot].leg

    def driving(self, robot: int) -> bool:
        return self.robots[robot].driving

    @property
    def finished(self) -> bool:
        return all(progress.leg is None for progress in self.robots)

    def startable(self) -> list[GoalOrder]:
        """The first goal of every robot now free to start its next leg (in robot order)."""
        orders = []
        for index, progress in enumerate(self.robots):
            leg = progress.leg
            if progress.driving or leg is None or not all(
                    self.robots[other].legs_done > other_leg
                    for other, other_leg in leg.waits_for):
                continue
            # From the later of the ends it follows: its own last leg's and those it waits for.
            stamp_s = max([*progress.ended_s[-1:], 0.0,
                           *(self.robots[other].ended_s[other_leg]
                             for other, other_leg in leg.waits_for)])
            pieces = max(1, math.ceil(math.dist(leg.start_m, leg.end_m)
                                      / self.spacings_m[index]))
            progress.points = [
                (leg.start_m[0] + (leg.end_m[0] - leg.start_m[0]) * k / pieces,
                 leg.start_m[1] + (leg.end_m[1] - leg.start_m[1]) * k / pieces)
                for k in range(1, pieces + 1)]
            progress.driving = True
            orders.append(self._next_point(index, stamp_s))
        return orders

    def _next_point(self, robot: int, stamp_s: float) -> GoalOrder:
        progress = self.robots[robot]
        assert progress.leg is not None
        goal = progress.points.pop(0)
        # The leg's end to the leg's tolerance (its task's camera), the points on the way looser.
        tolerance = progress.leg.tolerance_m if not progress.points else WAYPOINT_TOLERANCE_M
        return GoalOrder(robot, goal, tolerance, stamp_s)

    def reached(self, robot: int, at_s: float = 0.0) -> tuple[GoalOrder | None, Leg | None]:
        """Robot ``robot`` reached its goal at ``at_s`` (simulated time): its next point (None
        when that ended its leg), and the leg it ended (whose tasks are then done; then call
        :meth:`startable`)."""
        progress = self.robots[robot]
        if progress.points:
            return self._next_point(robot, at_s), None
        ended = progress.leg
        progress.ended_s.append(at_s)
        progress.legs_done += 1
        progress.driving = False
        return None, ended
