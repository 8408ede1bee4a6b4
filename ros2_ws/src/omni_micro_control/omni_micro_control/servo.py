"""The servo mode: keep the robot rolling and correct it from the captures in motion (no rclpy).

The paper's rule and the model mode stop the robot for every capture. This mode stops once at the
start (to see where the robot is) and once at the end (to confirm it), and in between corrects
the move from the captures of the moving robot (:mod:`omni_micro_vision.motion_capture`):

- **The estimate** is an extended Kalman filter over the slip core
  (:mod:`omni_micro_control.slip_filter`): the pose and the assembly offsets xi2, xi3, the model
  fed the same wheel commands as the robot, every capture taken in at its stamp (mid-exposure).
- **Latency.** A capture arrives after its stamp, at most ``capture_age_s`` after it (the
  cameras say how much: :func:`omni_micro_vision.motion_capture.capture_age_bound_s`). The new
  command starts ``capture_age_s + command_lead_s`` after the capture's stamp (on the robot's
  command grid, ``command_period_s``: the dynamics starts a command on its next tick, and a plan
  that assumed otherwise misses by what the crawl rolls in a tick), so that when it starts is a
  function of the capture, never of when its message came; it is planned from where
  the model has the robot then: the estimate at the capture's stamp carried through the
  commands already sent.
- **The plan** shoots through the slip core from that rolling state: the steering angle and the
  wheels' rotation whose predicted stop is the goal (Newton's method, finite differences). The
  wheels go on from the speed they have, at cruise, down to a slow crawl for the last
  ``crawl_m`` (the micro camera's captures are sharp at crawl), and to rest on the goal. Within
  ``freeze_steering_m`` of the goal only the rotation is replanned.
- **What the steering allows while rolling.** With the paper's exact, instantaneous steering a
  new angle acts at once and the wheels keep their speed (the slip model's assumption). A
  steering motion (``--steering realistic``: a gear train, backlash) stops the wheels while they
  steer (:mod:`omni_micro_sim.steering`), so re-steering while rolling would stop the robot at
  every capture: with one the servo steers only from rest and, rolling, replans the rotation
  alone (how far along the course); what the course misses across is corrected by a short move
  after the stop.

One stop at the end averages ``captures_per_stop`` captures of the sharpest camera: within the
tolerance (its 95 % radius included) the goal is reached; else one more move from there.
"""

from __future__ import annotations

import math

import numpy as np

from omni_micro_control.feedback import (
    Finished,
    Outcome,
)
from omni_micro_control.observations import Observation, mean_observation
from omni_micro_control.servo_config import ServoCommand, ServoConfig, ServoPhase
from omni_micro_control.slip_filter import SlipFilter
from omni_micro_sim.errors import SimulationError
from omni_micro_sim.open_loop import run_to_rest
from omni_micro_sim.parameters import MotorLimits, RobotParameters
from omni_micro_sim.profile import WheelSpeedProfile
from omni_micro_sim.state import RobotState
from omni_micro_sim.steering import plan_steering

# The smallest change of a wheel speed (rad/s) that needs a knot of its own.
_SPEED_EPS = 1e-9
# The shortest stretch between two knots: a microsecond, well above a stamp's nanosecond.
_SHORTEST_S = 1e-6
# Finite differences of the shooting: steering (rad) and wheel rotation (rad).
_STEERING_STEP_RAD = 1e-5
_ROTATION_STEP_RAD = 1e-3
_MAX_STEERING_STEP_RAD = 0.1


def profile_to(speed_rad_s: float, rotation_rad: float, limits: MotorLimits,
               crawl_speed_rad_s: float, crawl_rotation_rad: float) -> WheelSpeedProfile:
    """Wheel speeds from ``speed_rad_s`` now that turn the wheels by ``rotation_rad`` and end
    at rest: up to the cruise speed (or as near as the rotation allows), down to the crawl
    speed for the last ``crawl_rotation_rad``, then to rest, within the motors' acceleration
    and deceleration. A rotation shorter than it takes to stop from this speed stops at once
    (the rotation is then longer than asked: the robot cannot brake harder)."""
    acc, dec = limits.acceleration_rad_s2, limits.deceleration_rad_s2
    w0 = max(0.0, float(speed_rad_s))
    rotation = max(0.0, float(rotation_rad))
    crawl = min(crawl_speed_rad_s, limits.cruise_speed_rad_s)
    knots: list[tuple[float, float]] = [(0.0, w0)]

    def knot(after_s: float, speed: float) -> None:
        time, _ = knots[-1]
        if after_s < _SHORTEST_S:
            knots[-1] = (time, speed)   # closer than a command's stamps tell apart
        else:
            knots.append((time + after_s, speed))

    def go(speed: float, hold_rad: float = 0.0) -> None:
        now = knots[-1][1]
        if abs(speed - now) > _SPEED_EPS:
            knot(abs(speed - now) / (acc if speed > now else dec), speed)
        if hold_rad > 0.0 and speed > 0.0:
            knot(hold_rad / speed, speed)

    def rotation_between(a: float, b: float) -> float:
        return abs(b * b - a * a) / (2.0 * (acc if b > a else dec))

    tail = crawl_rotation_rad + crawl * crawl / (2.0 * dec)
    if rotation <= tail + rotation_between(w0, crawl) or w0 * w0 / (2.0 * dec) >= rotation:
        # Within the final approach: at most the crawl speed (less if that overshoots).
        peak = min(crawl, math.sqrt(2.0 * dec * rotation)) if rotation > 0 else 0.0
        if w0 * w0 / (2.0 * dec) >= rotation:
            peak = 0.0
        hold = rotation - rotation_between(w0, peak) - peak * peak / (2.0 * dec)
        go(peak, hold if peak > 0.0 else 0.0)
        go(0.0)
    else:
        main = rotation - tail

        def covered(peak: float) -> float:
            return rotation_between(w0, peak) + rotation_between(peak, crawl)

        peak = limits.cruise_speed_rad_s
        if covered(peak) > main:
            # (p^2 - w0^2) / 2acc + (p^2 - c^2) / 2dec = main, for p >= w0, c.
            squared = ((main + w0 * w0 / (2.0 * acc) + crawl * crawl / (2.0 * dec))
                       / (1.0 / (2.0 * acc) + 1.0 / (2.0 * dec)))
            peak = math.sqrt(max(squared, max(w0, crawl) ** 2))
        go(peak, max(0.0, main - covered(peak)))
        go(crawl, crawl_rotation_rad)
        go(0.0)
    if len(knots) == 1:
        knots.append((1e-3, 0.0))
    elif knots[-1][1] != 0.0:
        knots[-1] = (knots[-1][0], 0.0)
    times, speeds = zip(*knots, strict=True)
    return WheelSpeedProfile(np.array(times), np.array(speeds))


def sharpest_mean(captures: list[Observation]) -> Observation:
    """The mean of the captures of the camera that sees the robot best (smallest 95 % radius)."""
    by_camera: dict[str, list[Observation]] = {}
    for seen in captures:
        by_camera.setdefault(seen.camera, []).append(seen)
    means = [mean_observation(group) for group in by_camera.values()]
    return min(means, key=lambda mean: mean.radius_95_m)


class ServoController:
    """Feed it the stationary captures, the captures in motion and the wheels' stop; it answers
    with commands and, at the end, the outcome. ``robot`` is what it knows of the robot: the
    nominal one, the steering's form included (never the true offsets or backlash)."""

    def __init__(self, config: ServoConfig, limits: MotorLimits, robot: RobotParameters) -> None:
        self.config = config
        self.limits = limits
        self.robot = robot
        self.phase = ServoPhase.DONE
        self.goal_m: tuple[float, float] | None = None
        self.command: ServoCommand | None = None
        self.filter: SlipFilter | None = None
        self.moves = 0
        self.stops = 0
        self.replans = 0
        self._steering_rad = 0.0
        self._settled_at = math.inf
        self._stop_captures: list[Observation] = []
        self._last_replan_s = -math.inf

    @property
    def rolls_while_steering(self) -> bool:
        """Whether a new angle acts while the wheels roll (the paper's exact steering)."""
        return self.robot.steering.instantaneous

    # -- inputs ------------------------------------------------------------------------------
    def set_goal(self, goal_m: tuple[float, float], now_s: float) -> None:
        """A goal for a robot at rest: its first stationary captures (from ``now_s``) start the
        move. Its moves, stops and plans made again are counted afresh (``max_moves`` is per
        goal); what the filter has learnt of the robot stays."""
        self.goal_m = (float(goal_m[0]), float(goal_m[1]))
        self.moves = self.stops = self.replans = 0
        self.phase = ServoPhase.SETTLING
        self._settled_at = now_s
        self._stop_captures = []

    def on_wheels_stopped(self, stamp_s: float) -> None:
        """The wheels have come to rest at the end of the command."""
        if self.phase is ServoPhase.ROLLING:
            self.phase = ServoPhase.SETTLING
            self.stops += 1
            self._settled_at = stamp_s + self.config.settle_wait_s
            self._stop_captures = []

    def on_capture(self, seen: Observation) -> ServoCommand | Finished | None:
        """A stationary capture: after the stop's settling, average, then confirm or move
        (a Finished's periods are the moves)."""
        if self.phase not in (ServoPhase.SETTLING, ServoPhase.CAPTURING) \
                or seen.stamp_s < self._settled_at:
            return None
        self.phase = ServoPhase.CAPTURING
        self._stop_captures.append(seen)
        if len(self._stop_captures) < self.config.captures_per_stop:
            return None
        mean = sharpest_mean(self._stop_captures)
        assert self.goal_m is not None
        distance = math.hypot(mean.x_m - self.goal_m[0], mean.y_m - self.goal_m[1])
        if distance + mean.radius_95_m <= self.config.tolerance_m:
            self.phase = ServoPhase.DONE
            return Finished(Outcome.REACHED, f'{distance * 1e6:.3f} um from the goal, '
                                 f'{mean.radius_95_m * 1e6:.3f} um 95 % radius', self.moves,
                                 mean)
        if self.moves >= self.config.max_moves:
            self.phase = ServoPhase.DONE
            return Finished(Outcome.GAVE_UP, f'{distance * 1e6:.3f} um from the goal after '
                                 f'{self.moves} moves', self.moves, mean)
        return self._move_from_rest(mean)

    def on_capture_in_motion(self, seen: Observation) -> ServoCommand | None:
        """A capture of the rolling robot: learn, then maybe replan (see the module: latency).

        Whether it counts is decided by its stamp alone, never by whether the wheels' stop came
        first: one stamped within the running command is taken in even after the stop (a node
        may receive the two in either order); one stamped after it is the stop's to decide.
        """
        command = self.command
        if self.phase is ServoPhase.DONE or self.filter is None or command is None \
                or seen.stamp_s > command.start_s + command.profile.end_time_s:
            return None
        self.filter.update(seen)
        if seen.stamp_s - self._last_replan_s < self.config.replan_period_s:
            return None
        start = self._on_grid(seen.stamp_s + self.config.capture_age_s
                              + self.config.command_lead_s)
        speed = self._commanded_speed(start)
        if speed <= _SPEED_EPS:
            return None     # the wheels are stopping: the stop decides
        state = self.filter.state_at(start)
        assert self.goal_m is not None
        remaining = math.hypot(self.goal_m[0] - state.x_m, self.goal_m[1] - state.y_m)
        keep_steering = (not self.rolls_while_steering
                         or remaining < self.config.freeze_steering_m)
        try:
            steering, profile = self._shoot(state, speed, command.steering_rad,
                                            self._rotation_left(start), keep_steering,
                                            wheels_rad=self.filter.wheels_steering_rad)
        except SimulationError:
            return None     # the plan did not settle: the running command goes on
        self._last_replan_s = seen.stamp_s
        self.replans += 1
        return self._send(ServoCommand(start, steering, profile, from_rest=False))

    # -- plans -------------------------------------------------------------------------------
    def _move_from_rest(self, mean: Observation) -> ServoCommand:
        self.moves += 1
        self.phase = ServoPhase.ROLLING
        if self.filter is None:
            self.filter = SlipFilter(self.robot, mean, self._steering_rad, self.config.filter)
        else:
            self.filter.restart(mean, self._steering_rad)
        assert self.goal_m is not None
        start = self._on_grid(mean.stamp_s + self.config.command_lead_s)
        state = RobotState(x_m=mean.x_m, y_m=mean.y_m, phi_rad=mean.phi_rad)
        aim = math.remainder(math.atan2(self.goal_m[1] - mean.y_m, self.goal_m[0] - mean.x_m)
                             - mean.phi_rad, 2.0 * math.pi)
        distance = math.hypot(self.goal_m[1] - mean.y_m, self.goal_m[0] - mean.x_m)
        wheels, profile = self._shoot(state, 0.0, aim, distance / self.robot.wheel_radius_m,
                                      keep_steering=False, from_rest=True)
        self._last_replan_s = mean.stamp_s
        return self._send(ServoCommand(start, self._gear_target(wheels), profile))

    def _on_grid(self, time_s: float) -> float:
        """The first tick of the robot's command grid at or after ``time_s`` (a hair of
        tolerance, as the dynamics has it, so that k * period lands on tick k)."""
        period = self.config.command_period_s
        return math.ceil(time_s / period - 1e-9) * period

    def _gear_target(self, wheels_rad: float) -> float:
        """The angle to command so that the wheels end at ``wheels_rad``: with a gear's play
        the wheels trail the gear by half the play (as the model has it) on the side it came
        from; a change smaller than a motor step is none."""
        steering = self.robot.steering
        assert self.filter is not None
        if steering.instantaneous:
            return wheels_rad
        now = self.filter.wheels_steering_rad
        if abs(wheels_rad - now) < max(steering.step_rad, 1e-12):
            return self._steering_rad
        return wheels_rad + math.copysign(0.5 * steering.backlash_rad, wheels_rad - now)

    def _send(self, command: ServoCommand) -> ServoCommand:
        assert self.filter is not None
        self.command = command
        self._steering_rad = command.steering_rad
        self.filter.command(command.start_s, command.steering_rad, command.profile)
        return command

    def _shoot(self, state: RobotState, speed: float, steering: float, rotation: float,
               keep_steering: bool, wheels_rad: float | None = None, from_rest: bool = False
               ) -> tuple[float, WheelSpeedProfile]:
        """The wheels' angle and rotation from ``state`` (wheels at ``speed``) whose predicted
        stop is the goal; with ``keep_steering`` only the rotation, so that the stop lies as far
        along the course as the goal (the wheels where the model has them, ``wheels_rad``: a
        gear's play leaves them off the commanded angle). From rest with a steering mechanism
        the prediction steers first, from where the model has gear and wheels to the gear
        target that leaves the wheels at the angle (:meth:`_gear_target`): the chassis turns
        while they steer."""
        assert self.goal_m is not None and self.filter is not None
        robot = self.filter.robot_estimate
        crawl_rad = self.config.crawl_m / self.robot.wheel_radius_m
        goal = np.array(self.goal_m)
        steers = from_rest and not robot.steering.instantaneous
        gear, wheels_now = self.filter.gear_rad, self.filter.wheels_steering_rad
        # A motor turns in steps: a smaller difference of angle would change nothing.
        steering_step = max(_STEERING_STEP_RAD, 2.0 * robot.steering.step_rad) if steers \
            else _STEERING_STEP_RAD

        def stop(angle: float, turn: float) -> np.ndarray:
            profile = profile_to(speed, turn, self.limits, self.config.crawl_speed_rad_s,
                                 crawl_rad)
            rolling_at = wheels_rad if keep_steering and wheels_rad is not None else angle
            motion = (plan_steering(robot.steering, gear, wheels_now, self._gear_target(angle))
                      if steers else None)
            final, _ = run_to_rest(robot, rolling_at, profile, state, motion=motion)
            return np.array([final.x_m, final.y_m])

        for _ in range(self.config.shooting_iterations):
            reached = stop(steering, rotation)
            miss = goal - reached
            if math.hypot(*miss) < self.config.shooting_tolerance_m:
                break
            along = (stop(steering, rotation + _ROTATION_STEP_RAD) - reached) / _ROTATION_STEP_RAD
            if float(along @ along) == 0.0:
                break    # the wheels cannot stop sooner than they do: nothing to shoot
            if keep_steering:
                # Only the rotation: the stop as far along the course as the goal.
                rotation += float(miss @ along) / float(along @ along)
            else:
                across = (stop(steering + steering_step, rotation) - reached) / steering_step
                step = np.linalg.lstsq(np.column_stack([across, along]), miss, rcond=None)[0]
                # Newton's step from where the Jacobian holds (a steering mechanism's steps make
                # it coarse): never more than a tenth of a radian of steering at once.
                steering += float(np.clip(step[0], -_MAX_STEERING_STEP_RAD,
                                          _MAX_STEERING_STEP_RAD))
                rotation += float(step[1])
            rotation = max(rotation, 0.0)
        return steering, profile_to(speed, rotation, self.limits, self.config.crawl_speed_rad_s,
                                    crawl_rad)

    def _commanded_speed(self, time_s: float) -> float:
        assert self.command is not None
        elapsed = max(0.0, time_s - self.command.start_s)
        return float(self.command.profile.speeds_at(elapsed)[1])

    def _rotation_left(self, time_s: float) -> float:
        """What the running command still turns the wheels from ``time_s``."""
        assert self.command is not None
        profile = self.command.profile
        elapsed = max(0.0, time_s - self.command.start_s)
        return float(profile.rotation_rad()[1] - profile.rotation_until(elapsed)[1])
