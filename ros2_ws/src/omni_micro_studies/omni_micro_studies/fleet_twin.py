"""The fleet's twin: several robots on one platform, in one process.

Each robot is the twin's robot (:mod:`omni_micro_studies.twin`): its own slip dynamics and
offsets, its own captures (the camera pair sees each robot; each capture is that robot's, as
its fiducial would say), and its controller (the paper's rule, the model mode or the servo, one
loop of the twin's for the whole run) driving it leg by leg through the fleet plan
(:mod:`omni_micro_control.fleet_plan`). A leg starts once the legs it waits for have
ended; every period the robots' chassis discs are checked against each other, and a contact
ends the run as a fault naming both robots (contact itself is not simulated: the slip model
has no force between robots).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from omni_micro_control.feedback import Finished, VisionFeedbackController
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.fleet_files import controller_settings
from omni_micro_control.fleet_legs import LEG_ENDS, GoalOrder, LegDispatcher
from omni_micro_control.fleet_plan import FleetPlan, PlanningError, Task
from omni_micro_control.fleet_roadmap import ROBOT_DIAMETER_M, point_segment_distance
from omni_micro_control.model_based import learnt_offsets, planner_for
from omni_micro_control.servo_config import SERVO_MODE
from omni_micro_control.servo_session import ServoSession
from omni_micro_control.tuning import retune
from omni_micro_sim.parameters import DEFAULT_PERIOD_S, MotorLimits, RobotParameters
from omni_micro_sim.state import RobotState
from omni_micro_sim.stepper import GridSimulator
from omni_micro_studies.twin import (
    ServoLoop,
    StopAndGoLoop,
    nominal_timings,
    twin_servo_config,
)
from omni_micro_vision.camera import DEFAULT_RIG, CameraRig, CaptureRule, StationaryCamera
from omni_micro_vision.motion_capture import MovingCamera

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
    # xi2, xi3 as its controller had learnt them at the end (the model mode, the servo).
    learnt_offsets_rad: tuple[float, float] | None = None
    # Each goal its controller was handed (stamp_s, x_m, y_m: every point of its legs, as the
    # graph's coordinator publishes them), and how each that ended did (at_s, outcome).
    goal_poses: list[tuple[float, float, float]] = field(default_factory=list)
    goal_pose_ends: list[tuple[float, str]] = field(default_factory=list)


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
    """One robot of the fleet: its dynamics, its camera's view of it, its controller in its mode,
    goal after goal as the robot's nodes take them (one controller for the run: what the model
    and the servo learn of the robot on one leg serves the next)."""

    def __init__(self, index: int, legs: LegDispatcher, robot: RobotParameters,
                 start: RobotState, seed: int, mode: str, limits: MotorLimits,
                 rig: CameraRig, rule: CaptureRule | None, period_s: float) -> None:
        self.index = index
        self.legs = legs
        self.grid = GridSimulator(robot, period_s=period_s, limits=limits, state=start)
        still = StationaryCamera(rig, rule, seed)
        self.loop: StopAndGoLoop | ServoLoop
        if mode == SERVO_MODE:
            timings = nominal_timings()
            session = ServoSession(twin_servo_config(None, timings, period_s), limits,
                                   RobotParameters())
            self.loop = ServoLoop(self.grid, still, MovingCamera(rig, timings, seed), session,
                                  limits)
        else:
            config = FeedbackConfig(**controller_settings(mode))  # type: ignore[arg-type]
            self.loop = StopAndGoLoop(self.grid, still, VisionFeedbackController(
                config, planner_for(config, None, limits, None)), limits)
        self.driving = False
        self.run = RobotRun(index)
        self.route: list[tuple[float, float, float, float]] = []

    def aim(self, order: GoalOrder) -> None:
        """The controller, sent to the next point of its leg with the leg's tolerance, as the
        coordinator sets it on the robot's controller node."""
        refused = retune(self.loop.controller, {'tolerance_m': order.tolerance_m})
        assert refused is None, refused   # the plan's tolerances are all valid
        self.loop.controller.set_goal(order.goal_m, order.stamp_s)
        self.run.goal_poses.append((order.stamp_s, *order.goal_m))
        self.driving = True

    @property
    def moves(self) -> int:
        return (self.loop.moves if isinstance(self.loop, ServoLoop)
                else len(self.loop.moves))

    def step(self) -> Finished | None:
        """One period: the robot moves, the camera sees it, the controller decides."""
        sample = self.grid.advance()
        state = sample.state
        self.route.append((sample.time_s, state.x_m, state.y_m, state.phi_rad))
        leg = self.legs.leg(self.index)
        if self.driving and leg is not None:
            self.run.off_leg_m = max(self.run.off_leg_m, float(point_segment_distance(
                np.array((state.x_m, state.y_m)), np.array(leg.start_m), np.array(leg.end_m))))
        finished = self.loop.step(sample)
        self.run.moves = self.moves
        return self._finish_leg(finished) if finished is not None else None

    def _finish_leg(self, finished: Finished) -> Finished | None:
        """The goal's end, at the stamp of what decided it (as its node reports it, and the
        coordinator hands out the next goal stamped so)."""
        self.driving = False
        at_s = self.loop.ended_at_s
        if finished.outcome in LEG_ENDS:
            self.run.goal_pose_ends.append((at_s, finished.outcome.value))
            following, leg = self.legs.reached(self.index, at_s)
            if following is not None:
                self.aim(following)
                return None
            assert leg is not None
            self.run.legs_done += 1
            state = self.grid.simulator.state
            for _ in leg.tasks:
                self.run.tasks_done_s.append(at_s)
                self.run.deviations_m.append(math.hypot(state.x_m - leg.end_m[0],
                                                        state.y_m - leg.end_m[1]))
        else:
            self.run.outcome = f'{finished.outcome.value}: {finished.reason}'
        return finished


def check_tolerances(tasks: list[list[Task]], rig: CameraRig = DEFAULT_RIG) -> None:
    """Raises PlanningError naming the first goal whose ``tolerance_um`` is no wider than the
    camera that sees the goal resolves (its captures' 95 % radius): the controller would end it
    ``unresolved``, however close the robot came."""
    for robot, goals in enumerate(tasks):
        for index, task in enumerate(goals):
            seen = rig.resolution_at(*task.goal_m)
            if task.tolerance_m is None or seen is None:
                continue   # the defaults fit their cameras; a goal off the platform is refused
            camera, radius_m = seen
            if task.tolerance_m <= radius_m:
                x_mm, y_mm = (v * 1e3 for v in task.goal_m)
                raise PlanningError(
                    f'robot {robot}\'s goal {index} at ({x_mm:g}, {y_mm:g}) mm: tolerance_um '
                    f'{task.tolerance_m * 1e6:g} is finer than the {camera} camera that sees it '
                    f'resolves (+-{radius_m * 1e6:.2f} um at 95 %): give more than '
                    f'{radius_m * 1e6:.2f}, or leave it out (the default: '
                    f'{task.default_tolerance_m() * 1e6:g} um there)')


def run_fleet(plan: FleetPlan, *, robots: list[RobotParameters], seed: int = 0,
              controllers: Sequence[str] | None = None, limits: MotorLimits | None = None,
              rig: CameraRig = DEFAULT_RIG, rule: CaptureRule | None = None,
              period_s: float = DEFAULT_PERIOD_S, max_sim_time_s: float = 1800.0,
              on_progress: Callable[[int, int, float], None] | None = None) -> FleetResult:
    """Drive every robot through its legs of ``plan``, robot k's controller in the mode
    ``controllers[k]`` (``paper``, ``model`` or ``servo``; the paper's rule for every robot by
    default), with the controller node's defaults.

    ``robots[k]`` is robot k's true robot (its offsets); the controllers know the nominal one.
    Robot k's captures draw their noise from ``seed`` and k. ``on_progress(done, total,
    sim_time_s)``, if given, is called each time a task is done.
    """
    limits = limits or MotorLimits()
    count = len(plan.starts_m)
    modes = list(controllers) if controllers is not None else ['paper'] * count
    if len(modes) != count:
        raise ValueError(f'{len(modes)} controller modes for {count} robots')
    dispatcher = LegDispatcher(plan, modes)
    fleet = [_Robot(k, dispatcher, robots[k],
                    RobotState(x_m=plan.starts_m[k][0], y_m=plan.starts_m[k][1]),
                    seed * 1000 + k, modes[k], limits, rig, rule, period_s)
             for k in range(count)]
    for robot, tasks in zip(fleet, plan.done_at_start, strict=True):
        robot.run.tasks_done_s += [0.0] * len(tasks)
        robot.run.deviations_m += [0.0] * len(tasks)
    closest, pair = math.inf, None
    outcome, reason = DONE, ''
    now_s = 0.0       # the robots' time
    ended_s = 0.0     # the latest goal's end: the run's time, as the graph's coordinator has it
    total = sum(len(tasks) for tasks in plan.tasks)
    done = 0
    while True:
        for order in dispatcher.startable():
            fleet[order.robot].aim(order)
        if dispatcher.finished:
            now_s = ended_s
            reason = f'every task done in {now_s:.2f} s'
            break
        if now_s > max_sim_time_s:
            outcome, reason = TIMEOUT, f'tasks left after {max_sim_time_s:g} s of simulated time'
            break
        finishes = [(robot, robot.step()) for robot in fleet]
        lost = [(robot, finished) for robot, finished in finishes
                if finished is not None and finished.outcome not in LEG_ENDS]
        now_s = fleet[0].grid.time_s
        ended_s = max(robot.loop.ended_at_s for robot in fleet)
        if on_progress is not None and sum(len(r.run.tasks_done_s) for r in fleet) > done:
            done = sum(len(r.run.tasks_done_s) for r in fleet)
            on_progress(done, total, ended_s)
        if lost:
            robot, finished = lost[0]
            outcome = LOST
            reason = f'robot {robot.index} {finished.outcome.value}: {finished.reason}'
            now_s = ended_s
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
        robot.run.learnt_offsets_rad = learnt_offsets(robot.loop.controller)
        robot.run.route_m = np.array(robot.route)
    return FleetResult(outcome, reason, now_s, [robot.run for robot in fleet], closest, pair)
