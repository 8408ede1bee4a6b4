"""The twin: the node graph's closed loop in one process, from the same core, camera model
and controller logic as the nodes.

Each grid period does what the three nodes do with one sample: the dynamics advances and
publishes, the camera sees the odometry, the controller sees the wheel state and the captures.
Every number crosses the same conventions it would in a message (nanosecond stamps, quaternion
headings, robot-frame twist), so with the same seed this ends on the graph's final pose; the
graph test checks that. Use it for sweeps, where starting processes would dominate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from omni_micro_common.conventions import (
    JOINT_NAMES,
    CaptureUncertainty,
    body_twist,
    quaternion_to_yaw,
    through_stamp,
    yaw_to_quaternion,
)
from omni_micro_control.feedback import (
    Finished,
    Move,
    Outcome,
    PaperRule,
    VisionFeedbackController,
)
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.model_based import ModelBasedPlanner, ModelConfig, planner_for
from omni_micro_control.move_watcher import MoveWatcher
from omni_micro_control.observations import Observation
from omni_micro_control.servo_config import ServoCommand, ServoConfig
from omni_micro_control.servo_session import ServoSession
from omni_micro_sim.errors import SimulationError
from omni_micro_sim.parameters import DEFAULT_PERIOD_S, MotorLimits, RobotParameters
from omni_micro_sim.profile import WheelSpeedProfile, move_profile
from omni_micro_sim.state import RobotState
from omni_micro_sim.stepper import GridSimulator, Sample
from omni_micro_sim.wheel_trajectory import (
    TrajectoryPoint,
    command_from_points,
    points_from_profile,
)
from omni_micro_vision.camera import DEFAULT_RIG, CameraRig, Capture, CaptureRule, StationaryCamera
from omni_micro_vision.motion_capture import (
    CameraTiming,
    MotionCapture,
    MovingCamera,
    capture_age_bound_s,
)


@dataclass
class ClosedLoopResult:
    outcome: Outcome
    reason: str
    periods: int
    final_state: RobotState
    sim_time_s: float
    goal_m: tuple[float, float]
    route_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # t, x, y
    moves: list[Move] = field(default_factory=list)
    planner: PaperRule | ModelBasedPlanner | None = None

    @property
    def deviation_m(self) -> float:
        return math.hypot(self.final_state.x_m - self.goal_m[0],
                          self.final_state.y_m - self.goal_m[1])


def capture_observation(capture: Capture | MotionCapture) -> Observation:
    """A capture as the controller node reads it from its message (the uncertainty crosses a
    PoseWithCovarianceStamped: variances)."""
    return Observation(through_stamp(capture.stamp_s), capture.x_m, capture.y_m,
                       quaternion_to_yaw(*yaw_to_quaternion(capture.phi_rad)), capture.camera,
                       CaptureUncertainty.from_covariance(capture.uncertainty.covariance()))


def schedule_move(grid: GridSimulator, steering_rad: float, profile: WheelSpeedProfile,
              start_s: float, now_s: float, limits: MotorLimits) -> None:
    """A command as the dynamics node receives it: it crosses a JointTrajectory, so its knot
    times become nanosecond stamps."""
    points = [TrajectoryPoint(through_stamp(point.time_from_start_s), point.positions,
                              point.velocities)
              for point in points_from_profile(steering_rad, profile)]
    grid.schedule(command_from_points(JOINT_NAMES, points, through_stamp(start_s), now_s,
                                      limits))


def _tick(grid: GridSimulator, max_sim_time_s: float,
          route: list[tuple[float, float, float]]) -> Sample:
    """One period of the robot, as the dynamics node publishes it, its pose kept in ``route``.

    Raises
    ------
    SimulationError
        Once past ``max_sim_time_s`` of simulated time with no outcome.
    """
    if grid.time_s > max_sim_time_s:
        raise SimulationError(f'no outcome within {max_sim_time_s} s of simulated time')
    sample = grid.advance()
    route.append((sample.time_s, sample.state.x_m, sample.state.y_m))
    return sample


def _drive(loop: StopAndGoLoop | ServoLoop, grid: GridSimulator,
           max_sim_time_s: float) -> tuple[Finished, np.ndarray]:
    """Period after period until ``loop`` ends its goal: how it ended, and the route (t, x, y).

    Raises
    ------
    SimulationError
        Once past ``max_sim_time_s`` of simulated time with no outcome.
    """
    route: list[tuple[float, float, float]] = []
    finished: Finished | None = None
    while finished is None:
        finished = loop.step(_tick(grid, max_sim_time_s, route))
    return finished, np.array(route)


class StopAndGoLoop:
    """One robot's stop-and-go loop (the paper's rule, or the model mode), a period at a time:
    what the vision and controller nodes do with one of the dynamics' samples. The fleet twin
    runs one per robot, goal after goal, as each robot's nodes run."""

    def __init__(self, grid: GridSimulator, camera: StationaryCamera,
                 controller: VisionFeedbackController, limits: MotorLimits) -> None:
        self.grid = grid
        self.camera = camera
        self.controller = controller
        self.limits = limits
        self.watcher = MoveWatcher()
        self.moves: list[Move] = []
        # When the last goal ended, as the node says it: the stamp of what decided it (a
        # capture's, the wheels' stop's, the camera's word), or the robot's time for a timeout.
        self.ended_at_s = 0.0

    def step(self, sample: Sample) -> Finished | None:
        """The sample seen by the camera and the wheel watcher, and the controller's answers
        carried out; the goal's end, if this sample ended it."""
        state = sample.state
        stamp = through_stamp(sample.time_s)
        decisions: list[tuple[Move | Finished | None, float]] = []
        if self.watcher.on_wheel_state(tuple(sample.wheel_rotations_rad),
                                       tuple(sample.wheel_speeds_rad_s),
                                       sample.steering_rate_rad_s):
            decisions.append((self.controller.on_wheels_stopped(stamp), stamp))
        forward, lateral = body_twist(state.phi_rad, state.vx_m_s, state.vy_m_s)
        for event in self.camera.on_odometry(stamp, state.x_m, state.y_m,
                                             quaternion_to_yaw(*yaw_to_quaternion(state.phi_rad)),
                                             math.hypot(forward, lateral), state.omega_rad_s):
            at_s = through_stamp(event.stamp_s)
            decisions.append((self.controller.on_capture(capture_observation(event))
                              if isinstance(event, Capture)
                              else self.controller.on_out_of_field(at_s), at_s))
        for decision, at_s in decisions:
            if isinstance(decision, Move):
                self.moves.append(decision)
                profile = move_profile(decision.duration_s, self.limits)
                self.watcher.expect(float(profile.rotation_rad()[MoveWatcher.WATCHED_WHEEL]))
                schedule_move(self.grid, decision.steering_rad, profile, decision.start_s,
                              stamp, self.limits)
            elif isinstance(decision, Finished):
                self.ended_at_s = at_s
                return decision
        finished = self.controller.on_time(stamp)[1]
        if finished is not None:
            self.ended_at_s = stamp
        return finished


def run_closed_loop(goal_m: tuple[float, float], *, robot: RobotParameters,
                    limits: MotorLimits | None = None,
                    config: FeedbackConfig | None = None, rig: CameraRig = DEFAULT_RIG,
                    rule: CaptureRule | None = None, seed: int = 0,
                    start: RobotState | None = None, period_s: float = DEFAULT_PERIOD_S,
                    max_sim_time_s: float = 600.0, model_robot: RobotParameters | None = None,
                    model: ModelConfig | None = None) -> ClosedLoopResult:
    """Drive the robot to ``goal_m`` as the graph would; stop at the controller's outcome.

    ``robot`` is the true robot; in the model mode (``config.mode``) the controller starts
    from ``model_robot`` (the nominal robot by default: no offsets), as the node does.

    Raises
    ------
    SimulationError
        If no outcome came within ``max_sim_time_s`` of simulated time.
    """
    limits = limits or MotorLimits()
    grid = GridSimulator(robot, period_s=period_s, limits=limits, state=start)
    planner = planner_for(config or FeedbackConfig(), model_robot, limits, model)
    loop = StopAndGoLoop(grid, StationaryCamera(rig, rule, seed),
                         VisionFeedbackController(config, planner), limits)
    loop.controller.set_goal(goal_m, 0.0)
    finished, route = _drive(loop, grid, max_sim_time_s)
    return ClosedLoopResult(finished.outcome, finished.reason, finished.periods,
                            grid.simulator.state, grid.time_s,
                            (float(goal_m[0]), float(goal_m[1])), route, loop.moves,
                            planner)


@dataclass
class ServoResult(ClosedLoopResult):
    stops: int = 0
    replans: int = 0
    captures_in_motion: int = 0
    offsets_rad: tuple[float, float] = (0.0, 0.0)




class ServoLoop:
    """One robot's servo loop, a period at a time: what the vision node (its captures still and
    in motion) and the controller node in the servo mode do with one of the dynamics' samples.
    The fleet twin runs one per robot, goal after goal."""

    def __init__(self, grid: GridSimulator, still: StationaryCamera, moving: MovingCamera,
                 session: ServoSession, limits: MotorLimits) -> None:
        self.grid = grid
        self.still = still
        self.moving = moving
        self.session = session
        self.limits = limits
        self.moves = 0    # commands from rest, over every goal
        self.ended_at_s = 0.0   # when the last goal ended: the stamp of what decided it

    @property
    def controller(self) -> ServoSession:
        """What decides, as :class:`StopAndGoLoop` names its own."""
        return self.session

    def step(self, sample: Sample) -> Finished | None:
        """The sample seen by both cameras and the wheels, the commands carried out; the goal's
        end, if this sample ended it."""
        state = sample.state
        stamp = through_stamp(sample.time_s)
        phi = quaternion_to_yaw(*yaw_to_quaternion(state.phi_rad))
        self.session.on_wheel_state(stamp, tuple(sample.wheel_speeds_rad_s))
        for capture in self.moving.on_odometry(stamp, state.x_m, state.y_m, phi, state.vx_m_s,
                                               state.vy_m_s):
            replanned = self.session.on_capture_in_motion(capture_observation(capture))
            if replanned is not None:
                self._schedule(replanned, stamp)
        forward, lateral = body_twist(state.phi_rad, state.vx_m_s, state.vy_m_s)
        for event in self.still.on_odometry(stamp, state.x_m, state.y_m, phi,
                                            math.hypot(forward, lateral), state.omega_rad_s):
            decision = (self.session.on_capture(capture_observation(event))
                        if isinstance(event, Capture)
                        else self.session.on_out_of_field(through_stamp(event.stamp_s)))
            if isinstance(decision, ServoCommand):
                self.moves += int(decision.from_rest)
                self._schedule(decision, stamp)
            elif isinstance(decision, Finished):
                self.ended_at_s = through_stamp(event.stamp_s)
                return decision
        return None

    def _schedule(self, command: ServoCommand, now_s: float) -> None:
        schedule_move(self.grid, command.steering_rad, command.profile, command.start_s, now_s,
                      self.limits)


def nominal_timings() -> dict[str, CameraTiming]:
    """Each camera's timing in motion as the shipped params have it."""
    return {name: CameraTiming() for name in ('macro', 'micro')}


def twin_servo_config(config: ServoConfig | None, timings: dict[str, CameraTiming],
                      period_s: float) -> ServoConfig:
    """The servo's settings as the graph's bringup completes them: it counts on captures in
    motion as old as these cameras make them, and starts commands on the dynamics' grid."""
    return replace(config or ServoConfig(),
                   capture_age_s=capture_age_bound_s(timings.values(), period_s),
                   command_period_s=period_s)


def run_servo(goal_m: tuple[float, float], *, robot: RobotParameters,
              limits: MotorLimits | None = None, config: ServoConfig | None = None,
              rig: CameraRig = DEFAULT_RIG, timings: dict[str, CameraTiming] | None = None,
              rule: CaptureRule | None = None, seed: int = 0, start: RobotState | None = None,
              period_s: float = DEFAULT_PERIOD_S, max_sim_time_s: float = 120.0,
              model_robot: RobotParameters | None = None) -> ServoResult:
    """Drive the robot to ``goal_m`` with the servo mode (:mod:`omni_micro_control.servo`):
    rolling, corrected from the captures in motion, a stop at the end to confirm. ``robot`` is
    the true robot; the servo knows ``model_robot`` (the nominal robot by default). ``timings``:
    each camera's in motion (:class:`omni_micro_vision.motion_capture.CameraTiming`, by name);
    ``rule``: when the still robot's captures come. The servo counts on captures in motion as
    old as these cameras make them (``capture_age_s``), as the graph's bringup sets it.

    Raises
    ------
    SimulationError
        If no outcome came within ``max_sim_time_s`` of simulated time.
    """
    limits = limits or MotorLimits()
    grid = GridSimulator(robot, period_s=period_s, limits=limits, state=start)
    timings = timings or nominal_timings()
    session = ServoSession(twin_servo_config(config, timings, period_s), limits,
                           model_robot or RobotParameters())
    loop = ServoLoop(grid, StationaryCamera(rig, rule, seed), MovingCamera(rig, timings, seed),
                     session, limits)
    session.set_goal(goal_m, 0.0)
    finished, route = _drive(loop, grid, max_sim_time_s)
    servo = session.servo
    learnt = servo.filter.offsets_rad if servo.filter is not None else (0.0, 0.0)
    return ServoResult(finished.outcome, finished.reason, finished.periods,
                       grid.simulator.state, grid.time_s, (float(goal_m[0]), float(goal_m[1])),
                       route,
                       stops=servo.stops, replans=servo.replans,
                       captures_in_motion=session.captures_in_motion, offsets_rad=learnt)
