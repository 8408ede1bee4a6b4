"""The micro-factory's twin: several robots on one platform, in one process.

Each robot is the twin's robot (:mod:`omni_micro_cli.twin`): its own slip dynamics and
offsets, its own captures (the camera pair sees each robot; each capture is that robot's, as
its fiducial would say), and the paper's controller driving it leg by leg through the fleet
plan (:mod:`omni_micro_control.fleet_plan`). A leg starts once the legs it waits for have
ended; every period the robots' chassis discs are checked against each other, and a contact
ends the run as a fault naming both robots (contact itself is not simulated: the slip model
has no force between robots).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from omni_micro_cli.twin import capture_observation, schedule_move
from omni_micro_common.conventions import (
    body_twist,
    quaternion_to_yaw,
    through_stamp,
    yaw_to_quaternion,
)
from omni_micro_control.feedback import (
    FeedbackConfig,
    Finished,
    Move,
    Outcome,
    VisionFeedbackController,
)
from omni_micro_control.fleet_legs import GoalOrder, LegDispatcher
from omni_micro_control.fleet_plan import FleetPlan
from omni_micro_control.fleet_roadmap import ROBOT_DIAMETER_M, point_segment_distance
from omni_micro_control.model_based import planner_for
from omni_micro_control.move_watcher import MoveWatcher
from omni_micro_sim.parameters import DEFAULT_PERIOD_S, MotorLimits, RobotParameters
from omni_micro_sim.profile import move_profile
from omni_micro_sim.state import RobotState
from omni_micro_sim.stepper import GridSimulator
from omni_micro_vision.camera import DEFAULT_RIG, CameraRig, Capture, CaptureRule, StationaryCamera

# What ended a fleet run.
DONE, LOST, CONTACT, TIMEOUT = 'done', 'lost', 'contact', 'timeout'


@dataclass
class RobotRun:
    """One robot's part of a fleet run."""

    robot: int
    legs_done: int = 0
    tasks_done_s: list[float] = field(default_factory=list)   # when each task was reached
    deviations_m: list[float] = field(default_factory=list)   # how close, per task
    moves: int = 0
    off_leg_m: float = 0.0                   # the farthest it strayed from a leg's segment
    outcome: str = ''                        # the last leg's outcome when it was not reached
    final_state: RobotState | None = None
    route_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))   # t, x, y, phi


@dataclass
class FleetResult:
    outcome: str                             # DONE, LOST, CONTACT or TIMEOUT
    reason: str
    sim_time_s: float
    robots: list[RobotRun]
    closest_gap_m: float                     # the smallest distance between two centres
    closest_pair: tuple[int, int] | None

    @property
    def tasks_done(self) -> int:
        return sum(len(run.tasks_done_s) for run in self.robots)

    @property
    def goals_per_minute(self) -> float:
        return 60.0 * self.tasks_done / self.sim_time_s if self.sim_time_s > 0 else 0.0


class _Robot:
    """One robot of the fleet: its dynamics, its camera's view of it, its controller."""

    def __init__(self, index: int, legs: LegDispatcher, robot: RobotParameters,
                 start: RobotState, seed: int, config: FeedbackConfig, limits: MotorLimits,
                 rig: CameraRig, rule: CaptureRule | None, period_s: float) -> None:
        self.index = index
        self.legs = legs
        self.config = config
        self.limits = limits
        self.grid = GridSimulator(robot, period_s=period_s, limits=limits, state=start)
        self.camera = StationaryCamera(rig, rule, seed)
        self.watcher = MoveWatcher()
        self.controller: VisionFeedbackController | None = None
        self.run = RobotRun(index)
        self.route: list[tuple[float, float, float, float]] = []

    def aim(self, order: GoalOrder, now_s: float) -> None:
        """The controller, sent to the next point of its leg, as the dispatcher says."""
        config = replace(self.config, tolerance_m=order.tolerance_m)
        self.controller = VisionFeedbackController(config, planner_for(config, None,
                                                                       self.limits, None))
        self.controller.set_goal(order.goal_m, now_s)

    def step(self) -> Finished | None:
        """One period: the robot moves, the camera sees it, the controller decides."""
        sample = self.grid.advance()
        state = sample.state
        self.route.append((sample.time_s, state.x_m, state.y_m, state.phi_rad))
        leg = self.legs.leg(self.index)
        if self.controller is not None and leg is not None:
            self.run.off_leg_m = max(self.run.off_leg_m, float(point_segment_distance(
                np.array((state.x_m, state.y_m)), np.array(leg.start_m), np.array(leg.end_m))))
        stamp = through_stamp(sample.time_s)
        forward, lateral = body_twist(state.phi_rad, state.vx_m_s, state.vy_m_s)
        events = self.camera.on_odometry(stamp, state.x_m, state.y_m,
                                         quaternion_to_yaw(*yaw_to_quaternion(state.phi_rad)),
                                         math.hypot(forward, lateral), state.omega_rad_s)
        controller = self.controller
        stopped = self.watcher.on_wheel_state(tuple(sample.wheel_rotations_rad),
                                              tuple(sample.wheel_speeds_rad_s),
                                              sample.steering_rate_rad_s)
        if controller is None:
            return None
        decisions = [controller.on_wheels_stopped(stamp)] if stopped else []
        for event in events:
            decisions.append(controller.on_capture(capture_observation(event))
                             if isinstance(event, Capture)
                             else controller.on_out_of_field(through_stamp(event.stamp_s)))
        for decision in decisions:
            if isinstance(decision, Move):
                self.run.moves += 1
                profile = move_profile(decision.duration_s, self.limits)
                self.watcher.expect(float(profile.rotation_rad()[MoveWatcher.WATCHED_WHEEL]))
                schedule_move(self.grid, decision.steering_rad, profile, decision.start_s,
                              stamp, self.limits)
            elif isinstance(decision, Finished):
                return self._finish_leg(decision, sample.time_s)
        finished = controller.on_time(stamp)[1]
        return self._finish_leg(finished, sample.time_s) if finished is not None else None

    def _finish_leg(self, finished: Finished, now_s: float) -> Finished | None:
        self.controller = None
        if finished.outcome is Outcome.REACHED:
            following, leg = self.legs.reached(self.index)
            if following is not None:
                self.aim(following, now_s)
                return None
            assert leg is not None
            self.run.legs_done += 1
            state = self.grid.simulator.state
            for _ in leg.tasks:
                self.run.tasks_done_s.append(now_s)
                self.run.deviations_m.append(math.hypot(state.x_m - leg.end_m[0],
                                                        state.y_m - leg.end_m[1]))
        else:
            self.run.outcome = f'{finished.outcome.value}: {finished.reason}'
        return finished


def run_fleet(plan: FleetPlan, *, robots: list[RobotParameters], seed: int = 0,
              config: FeedbackConfig | None = None, limits: MotorLimits | None = None,
              rig: CameraRig = DEFAULT_RIG, rule: CaptureRule | None = None,
              period_s: float = DEFAULT_PERIOD_S, max_sim_time_s: float = 1800.0,
              on_progress: Callable[[int, int, float], None] | None = None) -> FleetResult:
    """Drive every robot through its legs of ``plan``, the paper's controller on each.

    ``robots[k]`` is robot k's true robot (its offsets); the controllers know the nominal one.
    Robot k's captures draw their noise from ``seed`` and k. ``on_progress(done, total,
    sim_time_s)``, if given, is called each time a task is done.
    """
    config = config or FeedbackConfig()
    limits = limits or MotorLimits()
    dispatcher = LegDispatcher(plan)
    fleet = [_Robot(k, dispatcher, robots[k],
                    RobotState(x_m=plan.starts_m[k][0], y_m=plan.starts_m[k][1]),
                    seed * 1000 + k, config, limits, rig, rule, period_s)
             for k in range(len(plan.starts_m))]
    for robot, tasks in zip(fleet, plan.done_at_start, strict=True):
        robot.run.tasks_done_s += [0.0] * len(tasks)
        robot.run.deviations_m += [0.0] * len(tasks)
    closest, pair = math.inf, None
    outcome, reason = DONE, ''
    now_s = 0.0
    total = sum(len(tasks) for tasks in plan.tasks)
    done = 0
    while True:
        for order in dispatcher.startable():
            fleet[order.robot].aim(order, now_s)
        if dispatcher.finished:
            reason = f'every task done in {now_s:.2f} s'
            break
        if now_s > max_sim_time_s:
            outcome, reason = TIMEOUT, f'tasks left after {max_sim_time_s:g} s of simulated time'
            break
        finishes = [(robot, robot.step()) for robot in fleet]
        lost = [(robot, finished) for robot, finished in finishes
                if finished is not None and finished.outcome is not Outcome.REACHED]
        now_s = fleet[0].grid.time_s
        if on_progress is not None and sum(len(r.run.tasks_done_s) for r in fleet) > done:
            done = sum(len(r.run.tasks_done_s) for r in fleet)
            on_progress(done, total, now_s)
        if lost:
            robot, finished = lost[0]
            outcome = LOST
            reason = f'robot {robot.index} {finished.outcome.value}: {finished.reason}'
            break
        positions = [(robot.grid.simulator.state.x_m, robot.grid.simulator.state.y_m)
                     for robot in fleet]
        for a, b in itertools.combinations(range(len(fleet)), 2):
            gap = math.dist(positions[a], positions[b])
            if gap < closest:
                closest, pair = gap, (a, b)
        if closest < ROBOT_DIAMETER_M and pair is not None:
            outcome = CONTACT
            reason = (f'robots {pair[0]} and {pair[1]} touched at {now_s:.2f} s: centres '
                      f'{closest * 1e3:.2f} mm apart, 9 mm discs')
            break
    for robot in fleet:
        robot.run.final_state = robot.grid.simulator.state
        robot.run.route_m = np.array(robot.route)
    return FleetResult(outcome, reason, now_s, [robot.run for robot in fleet], closest, pair)
