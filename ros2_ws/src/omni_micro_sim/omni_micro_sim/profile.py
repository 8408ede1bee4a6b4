"""Wheel commands: a steering angle and piecewise-linear wheel speeds in time.

Section 3.5: the wheels ramp at +50 rad/s^2 to 8.7 rad/s, hold, and ramp down at -50 rad/s^2 so
that the commanded wheel rotation equals 8.7 rad/s times the move time t. A move too short to
reach 8.7 rad/s is a triangle with the same rotation. Steering is exact and instantaneous.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim import knots
from omni_micro_sim.errors import CommandError
from omni_micro_sim.parameters import MotorLimits

WHEEL_COUNT = 3


@dataclass(frozen=True, eq=False)
class WheelSpeedProfile:
    """Wheel spin speeds (rad/s) at knot times (s from the start of the move), linear between.

    After the last knot the speeds stay at their last value; a move ends at rest when the last
    knot's speeds are zero.
    """

    knot_times_s: np.ndarray
    knot_speeds_rad_s: np.ndarray

    def __post_init__(self) -> None:
        times = np.array(self.knot_times_s, dtype=np.float64, copy=True).reshape(-1)
        speeds = np.array(self.knot_speeds_rad_s, dtype=np.float64, copy=True)
        if speeds.ndim == 1:
            speeds = np.repeat(speeds[:, None], WHEEL_COUNT, axis=1)
        if times.size == 0:
            raise CommandError('a wheel speed profile needs at least one knot, got none')
        if speeds.shape != (times.size, WHEEL_COUNT):
            raise CommandError(
                f'knot_speeds_rad_s must have shape ({times.size}, {WHEEL_COUNT}), '
                f'got {speeds.shape}')
        if not np.all(np.isfinite(times)):
            raise CommandError(f'knot times must be finite, got {times.tolist()}')
        if not np.all(np.isfinite(speeds)):
            raise CommandError(f'knot speeds must be finite, got {speeds.tolist()}')
        if times[0] < 0.0:
            raise CommandError(f'knot times must be >= 0, got {times[0]!r} s')
        if np.any(np.diff(times) <= 0.0):
            raise CommandError(f'knot times must increase strictly, got {times.tolist()}')
        times.setflags(write=False)
        speeds.setflags(write=False)
        object.__setattr__(self, 'knot_times_s', times)
        object.__setattr__(self, 'knot_speeds_rad_s', speeds)

    @property
    def end_time_s(self) -> float:
        return float(self.knot_times_s[-1])

    @property
    def ends_at_rest(self) -> bool:
        return bool(np.all(self.knot_speeds_rad_s[-1] == 0.0))

    def speeds_at(self, time_s: float) -> np.ndarray:
        """Speeds of the three wheels at ``time_s`` after the start of the move."""
        speeds = np.empty(WHEEL_COUNT)
        # The kernel the integrator uses: no per-wheel Python loop in the closed loop's per-tick
        # path. Imported here: building a command (rotation_until) must not load numba.
        from omni_micro_sim import integrator

        integrator.speeds_at(float(time_s), self.knot_times_s, self.knot_speeds_rad_s,
                             self.knot_times_s.size, speeds)
        return speeds

    def rotation_rad(self) -> np.ndarray:
        """Rotation of each wheel from the start of the move to its last knot."""
        return self.rotation_until(self.end_time_s)

    def rotation_until(self, time_s: float) -> np.ndarray:
        """Rotation of each wheel from the start of the move (time 0) to ``time_s``.

        The speeds are piecewise linear, so the trapezoid rule over the knots is exact.
        """
        rotation = np.empty(WHEEL_COUNT)
        knots.rotation_until(float(time_s), self.knot_times_s, self.knot_speeds_rad_s,
                               self.knot_times_s.size, rotation)
        return rotation

    def check_limits(self, limits: MotorLimits) -> None:
        """Raise CommandError if any speed or speed change exceeds the motors' limits."""
        fastest = float(np.max(np.abs(self.knot_speeds_rad_s)))
        if fastest > limits.max_speed_rad_s * (1.0 + 1e-9):
            raise CommandError(
                f'wheel speed {fastest:.6g} rad/s exceeds the motor limit '
                f'{limits.max_speed_rad_s:.6g} rad/s')


def move_profile(duration_s: float, limits: MotorLimits | None = None) -> WheelSpeedProfile:
    """The section 3.5 profile for a move of ``duration_s`` at cruise speed.

    The wheels turn by ``cruise_speed * duration_s`` in all: a trapezoid lasting
    ``duration_s + (ramp up + ramp down)/2``, or a triangle when the move is too short to reach
    the cruise speed.

    Raises
    ------
    CommandError
        If ``duration_s`` is not a finite number > 0.
    """
    limits = limits or MotorLimits()
    try:
        duration = float(duration_s)
    except (TypeError, ValueError):
        raise CommandError(
            f'move duration must be a number of seconds, got {duration_s!r}') from None
    if not math.isfinite(duration) or duration <= 0.0:
        raise CommandError(
            f'move duration must be a finite number of seconds > 0, got {duration_s!r}')
    cruise = limits.cruise_speed_rad_s
    ramp_up = cruise / limits.acceleration_rad_s2
    ramp_down = cruise / limits.deceleration_rad_s2
    rotation = cruise * duration
    full_ramps_rotation = 0.5 * cruise * (ramp_up + ramp_down)
    if rotation >= full_ramps_rotation:
        hold = (rotation - full_ramps_rotation) / cruise
        times = [0.0, ramp_up, ramp_up + hold, ramp_up + hold + ramp_down]
        speeds = [0.0, cruise, cruise, 0.0]
        if hold == 0.0:
            times, speeds = times[:2] + times[3:], speeds[:2] + speeds[3:]
    else:
        # Triangle: peak^2 * (1/(2a) + 1/(2d)) = rotation.
        half_inverse = 0.5 / limits.acceleration_rad_s2 + 0.5 / limits.deceleration_rad_s2
        peak = math.sqrt(rotation / half_inverse)
        up = peak / limits.acceleration_rad_s2
        times = [0.0, up, up + peak / limits.deceleration_rad_s2]
        speeds = [0.0, peak, 0.0]
    return WheelSpeedProfile(np.array(times), np.array(speeds))


@dataclass(frozen=True)
class WheelCommand:
    """A steering angle and wheel speed profile to start at ``start_s`` (simulated seconds).

    ``profile=None`` is a stop: the wheels ramp down at the motors' deceleration.
    """

    start_s: float
    steering_rad: float = 0.0
    profile: WheelSpeedProfile | None = None

    @property
    def is_stop(self) -> bool:
        return self.profile is None
