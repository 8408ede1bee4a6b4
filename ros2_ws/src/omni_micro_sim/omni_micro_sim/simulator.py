"""The stepping API around the kernels.

:class:`SlipSimulator` holds a state and the wheel command being executed; ``step(dt)`` advances
simulated time exactly through the command's knots. Everything that integrates the robot, the ROS
node included, goes through it or through :func:`.open_loop.simulate_open_loop_batch`.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim import integrator, kernels
from omni_micro_sim.errors import CommandError, SimulationError
from omni_micro_sim.parameters import KERNEL_INDEX, MotorLimits, RobotParameters, require_finite
from omni_micro_sim.profile import WHEEL_COUNT, WheelSpeedProfile, move_profile
from omni_micro_sim.state import RobotState
from omni_micro_sim.steering import SteeringMotion, plan_steering

# RK4 step: with p = 1000 the fastest friction time constant is ~0.4 ms; 0.4 ms steps agree with
# a solve_ivp reference at rtol 1e-10 to far better than 0.1 um (tests/sim/test_physics.py).
DEFAULT_MAX_STEP_S = 4.0e-4
# "At rest": translation and rim speed of the rotation below 1 nm/s.
DEFAULT_REST_SPEED_M_S = 1.0e-9


class MotionStatus(enum.Enum):
    """What the simulated robot is doing."""

    IDLE = 'idle'          # no command running and at rest
    MOVING = 'moving'      # executing a wheel speed profile
    SETTLING = 'settling'  # profile finished, the body still slides


@dataclass(frozen=True)
class ContactSlip:
    """Slip velocities of the three wheel contacts (m/s): along and across each wheel."""

    longitudinal_m_s: np.ndarray
    transverse_m_s: np.ndarray


def wheel_headings_rad(params: RobotParameters, steering_rad: float) -> np.ndarray:
    """Body-frame rolling direction of each wheel: the common steering angle plus its offset."""
    return steering_rad + wheel_offsets(params)


def wheel_offsets(params: RobotParameters) -> np.ndarray:
    return np.asarray(params.wheel_offsets_rad, dtype=np.float64)


def delayed(profile: WheelSpeedProfile, delay_s: float) -> WheelSpeedProfile:
    """``profile`` started ``delay_s`` later, the wheels still until then (they steer first)."""
    if delay_s <= 0.0:
        return profile
    return WheelSpeedProfile(np.concatenate(([0.0], profile.knot_times_s + delay_s)),
                             np.vstack([np.zeros(WHEEL_COUNT), profile.knot_speeds_rad_s]))


STANDING = WheelSpeedProfile(np.zeros(1), np.zeros((1, WHEEL_COUNT)))


def check_step(name: str, value: float) -> float:
    number = float(value)
    if not math.isfinite(number) or number <= 0.0:
        raise CommandError(f'{name} must be a finite number of seconds > 0, got {value!r}')
    return number


class SlipSimulator:
    """Integrates the robot through wheel commands in simulated time.

    Parameters
    ----------
    params : the robot.
    state : initial state (at rest at the origin by default).
    steering_rad : the wheels' (and the steering gear's) initial angle.
    max_step_s : longest RK4 step.
    rest_speed_m_s : speed under which the robot counts as at rest.
    """

    def __init__(self, params: RobotParameters, state: RobotState | None = None, *,
                 steering_rad: float = 0.0, max_step_s: float = DEFAULT_MAX_STEP_S,
                 rest_speed_m_s: float = DEFAULT_REST_SPEED_M_S) -> None:
        self.params = params
        self._kernel_params = params.as_kernel_array()
        self._state = (state or RobotState()).as_array()
        self._max_step = check_step('max_step_s', max_step_s)
        self._rest_speed = check_step('rest_speed_m_s', rest_speed_m_s)
        self._time_s = 0.0
        self._offsets = wheel_offsets(params)
        initial = require_finite('initial steering angle', steering_rad)
        self._steering_target = initial
        self._motion = SteeringMotion.still(initial)
        self._profile = STANDING
        self._move_start_s = 0.0
        # Wheel rotation accumulated by finished commands; the running one adds its own part.
        self._rotation_before_move = np.zeros(WHEEL_COUNT)

    # -- state -------------------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        return self._time_s

    @property
    def state(self) -> RobotState:
        return RobotState.from_array(self._state)

    @property
    def steering_rad(self) -> float:
        """The wheels' common steering angle now (the commanded one, with exact steering)."""
        return self._motion.wheel_at(self.move_time_s)[0]

    @property
    def gear_rad(self) -> float:
        """The steering gear's angle now, as wheel angle (the wheels' own with exact steering;
        with a play, up to half of it away)."""
        return self._motion.gear_at(self.move_time_s)[0]

    @property
    def steering_rate_rad_s(self) -> float:
        return self._motion.wheel_at(self.move_time_s)[1]

    @property
    def steering_time_s(self) -> float:
        """How long the last command steered before the wheels could roll."""
        return self._motion.duration_s

    def _geometry(self) -> np.ndarray:
        return kernels.wheel_geometry(self.steering_rad + self._offsets, self._kernel_params)

    @property
    def running_profile(self) -> WheelSpeedProfile:
        """The wheel speeds of the running command from its start, the steering's wait included."""
        return self._profile

    @property
    def move_time_s(self) -> float:
        return self._time_s - self._move_start_s

    @property
    def status(self) -> MotionStatus:
        if self.move_time_s < self._profile.end_time_s or not self._profile.ends_at_rest:
            return MotionStatus.MOVING
        if integrator.is_at_rest(self._state, self._kernel_params, self._rest_speed):
            return MotionStatus.IDLE
        return MotionStatus.SETTLING

    def wheel_speeds(self) -> np.ndarray:
        """Commanded spin speeds (rad/s); a passive wheel 1 reports its free-rolling speed."""
        speeds = self._profile.speeds_at(self.move_time_s)
        if not self.params.wheel1_active:
            # Free rolling: the spin that cancels the longitudinal contact velocity, i.e. the
            # body's contact velocity along W_1 (the slip of a driven wheel at zero spin) over r.
            driven = self._kernel_params.copy()
            driven[KERNEL_INDEX['wheel1_drive']] = 1.0
            speeds[0] = 0.0
            slip_long, scratch = np.empty(3), np.empty((3, 3))
            kernels.contact_terms(self._state, speeds, self.steering_rate_rad_s,
                                  self._geometry(), driven, slip_long, scratch[0], scratch[1],
                                  scratch[2])
            speeds[0] = slip_long[0] / self.params.wheel_radius_m
        return speeds

    def wheel_rotations_rad(self) -> np.ndarray:
        """Total commanded rotation of each wheel since the simulator started."""
        rotation: np.ndarray = (self._rotation_before_move
                                + self._profile.rotation_until(self.move_time_s))
        return rotation

    def slip(self) -> ContactSlip:
        """Longitudinal and transverse slip of each contact now."""
        slip_long = np.empty(3)
        slip_trans = np.empty(3)
        scratch = np.empty((2, 3))
        kernels.contact_terms(self._state, self._profile.speeds_at(self.move_time_s),
                              self.steering_rate_rad_s, self._geometry(), self._kernel_params,
                              slip_long, slip_trans, scratch[0], scratch[1])
        return ContactSlip(slip_long, slip_trans)

    # -- commands ----------------------------------------------------------------------------
    def command(self, steering_rad: float, profile: WheelSpeedProfile,
                limits: MotorLimits | None = None) -> None:
        """Steer to ``steering_rad`` and run ``profile`` from now on.

        With the paper's exact, instantaneous steering the wheels roll at once; with a steering
        motion (``params.steering``) they first steer, still, then run ``profile``. Commanding
        the angle already commanded steers no further. A command replaces whatever was running.

        Raises
        ------
        CommandError
            If the steering angle is not finite or the profile breaks the motor limits.
        """
        try:
            steering = require_finite('steering angle', steering_rad)
        except ValueError as error:
            raise CommandError(str(error)) from None
        if limits is not None:
            profile.check_limits(limits)
        self._rotation_before_move = self.wheel_rotations_rad()
        now = self.move_time_s
        wheel = self._motion.wheel_at(now)[0]
        gear = self._motion.gear_at(now)[0]
        if steering == self._steering_target and not self.params.steering.instantaneous:
            self._motion = SteeringMotion.still(wheel, gear)
        else:
            self._motion = plan_steering(self.params.steering, gear, wheel, steering)
        self._steering_target = steering
        self._profile = delayed(profile, self._motion.duration_s)
        self._move_start_s = self._time_s

    def command_move(self, steering_rad: float, duration_s: float,
                     limits: MotorLimits | None = None) -> WheelSpeedProfile:
        """Command the section 3.5 profile for a move of ``duration_s`` along ``steering_rad``."""
        profile = move_profile(duration_s, limits)
        self.command(steering_rad, profile, limits)
        return profile

    def stop(self, limits: MotorLimits | None = None) -> None:
        """Ramp every wheel down to rest at the motors' deceleration, keeping the steering."""
        limits = limits or MotorLimits()
        speeds = self._profile.speeds_at(self.move_time_s)
        ramp = float(np.max(np.abs(speeds))) / limits.deceleration_rad_s2
        if ramp == 0.0:
            profile = STANDING
        else:
            profile = WheelSpeedProfile(np.array([0.0, ramp]), np.vstack([speeds, np.zeros(3)]))
        # The steering stops where it is (the same target steers no further).
        self.command(self._steering_target, profile)

    # -- what an estimator changes ------------------------------------------------------------
    def with_robot(self, params: RobotParameters) -> SlipSimulator:
        """A copy at the same time and state, running the same command, on ``params``: another
        guess of the robot (its offsets, its friction), with the same steering mechanism."""
        if params.steering != self.params.steering:
            raise CommandError('with_robot keeps the steering mechanism: the running steering '
                               'motion was planned with it')
        copy = SlipSimulator.__new__(SlipSimulator)
        copy.__dict__.update(self.__dict__)
        copy.params = params
        copy._kernel_params = params.as_kernel_array()
        copy._offsets = wheel_offsets(params)
        copy._state = self._state.copy()
        copy._rotation_before_move = self._rotation_before_move.copy()
        return copy

    def move_by(self, dx_m: float, dy_m: float, dphi_rad: float) -> None:
        """Shift and turn the robot in the plane, its velocity turned with it: an estimator's
        correction of where the robot is (the motion itself is unchanged)."""
        cos_d, sin_d = math.cos(dphi_rad), math.sin(dphi_rad)
        x, y, phi, vx, vy, omega = self._state
        self._state[:] = (x + dx_m, y + dy_m, phi + dphi_rad, cos_d * vx - sin_d * vy,
                          sin_d * vx + cos_d * vy, omega)

    # -- time --------------------------------------------------------------------------------
    def step(self, dt_s: float) -> RobotState:
        """Advance simulated time by ``dt_s`` and return the new state.

        Raises
        ------
        CommandError
            If ``dt_s`` is not a finite number > 0.
        SimulationError
            If the integration produced a non-finite state (the state is left as it was).
        """
        dt = check_step('dt_s', dt_s)
        start = self.move_time_s
        saved = self._state.copy()
        profile = self._profile
        steer = self._motion.wheel_knots
        ok = integrator.advance(self._state, start, start + dt, profile.knot_times_s,
                                profile.knot_speeds_rad_s, profile.knot_times_s.size, steer,
                                steer.shape[0], self._offsets, self._kernel_params,
                                self._max_step)
        if not ok:
            self._state = saved
            raise SimulationError(
                f'integration became non-finite between t={self._time_s:.6f} s and '
                f't={self._time_s + dt:.6f} s; state kept at {saved.tolist()}')
        self._time_s += dt
        return self.state


