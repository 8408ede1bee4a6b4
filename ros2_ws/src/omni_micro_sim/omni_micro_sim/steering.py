"""The steering motion (eq. S1 of docs/model.md): the steering motor's rate- and acceleration-
limited move, through the gear train and its backlash, to the wheels' common angle.

The paper takes the steering as exact and instantaneous; :class:`SteeringMotion` is what the
robot does instead when :attr:`SteeringParameters.instantaneous` is off. The motor runs a
trapezoidal (or triangular) profile from the gear's angle to the commanded angle, rounded to
whole motor steps and taken the short way round. The wheels sit somewhere in the backlash band
around the gear; they stay put until the gear's flank reaches them (a reversal first crosses the
band), then follow it half a band behind. The wheels' own steering inertia is neglected against
the motor's stiffness, so this is kinematics: the pivot friction they meet acts on the chassis
(eq. S2, in the kernels). Plain Python: building a command does not load numba.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim import knots
from omni_micro_sim.parameters import SteeringParameters


def _still_knots(angle_rad: float) -> np.ndarray:
    return np.array([[0.0, angle_rad, 0.0, 0.0]])


@dataclass(frozen=True, eq=False)
class SteeringMotion:
    """One steering move, in time from the command's start.

    ``gear_knots`` is the gear's output angle (as wheel steering angle), ``wheel_knots`` the
    wheels' common angle psi(t); both rows ``[t_start, angle, rate, acceleration]``.
    """

    gear_knots: np.ndarray
    wheel_knots: np.ndarray
    duration_s: float

    @classmethod
    def still(cls, angle_rad: float, gear_rad: float | None = None) -> SteeringMotion:
        """No motion: the wheels hold ``angle_rad``, the gear ``gear_rad`` (default: the same)."""
        gear = angle_rad if gear_rad is None else gear_rad
        return cls(_still_knots(gear), _still_knots(angle_rad), 0.0)

    def wheel_at(self, time_s: float) -> tuple[float, float]:
        """The wheels' steering angle (rad) and rate (rad/s) at ``time_s``."""
        return knots_state(self.wheel_knots, time_s)

    def gear_at(self, time_s: float) -> tuple[float, float]:
        return knots_state(self.gear_knots, time_s)

    @property
    def final_wheel_rad(self) -> float:
        return float(self.wheel_knots[-1, 1])

    @property
    def final_gear_rad(self) -> float:
        return float(self.gear_knots[-1, 1])


def motor_target(steering: SteeringParameters, gear_rad: float, target_rad: float) -> float:
    """Where the motor goes for ``target_rad``: the equivalent angle nearest the gear (the short
    way round), rounded to a whole number of motor steps."""
    target = target_rad + 2.0 * math.pi * round((gear_rad - target_rad) / (2.0 * math.pi))
    if steering.step_rad > 0.0:
        target = round(target / steering.step_rad) * steering.step_rad
    return target


def _gear_profile(start: float, end: float, rate: float,
                  acceleration: float) -> tuple[list[list[float]], float]:
    """Trapezoidal (or triangular) knots from ``start`` to ``end`` and their duration."""
    distance = abs(end - start)
    sign = 1.0 if end >= start else -1.0
    if distance == 0.0:
        return [[0.0, start, 0.0, 0.0]], 0.0
    if distance >= rate * rate / acceleration:
        ramp = rate / acceleration
        cruise = (distance - rate * ramp) / rate
        ramp_angle = 0.5 * acceleration * ramp * ramp
        rows = [[0.0, start, 0.0, sign * acceleration]]
        if cruise > 0.0:
            rows.append([ramp, start + sign * ramp_angle, sign * rate, 0.0])
        rows.append([ramp + cruise, end - sign * ramp_angle, sign * rate, -sign * acceleration])
        duration = 2.0 * ramp + cruise
    else:
        ramp = math.sqrt(distance / acceleration)
        peak = acceleration * ramp
        rows = [[0.0, start, 0.0, sign * acceleration],
                [ramp, start + sign * 0.5 * distance, sign * peak, -sign * acceleration]]
        duration = 2.0 * ramp
    rows.append([duration, end, 0.0, 0.0])
    return rows, duration


def _time_travelled(rows: list[list[float]], travel: float, sign: float) -> float:
    """When the gear has moved ``travel`` (>= 0) from its start, along ``sign``."""
    start = rows[0][1]
    for index, (begin, angle, rate, acceleration) in enumerate(rows[:-1]):
        end_time = rows[index + 1][0]
        left = sign * (start + sign * travel - angle)   # still to go from this row's start
        span = end_time - begin
        covered = sign * (rate * span + 0.5 * acceleration * span * span)
        if left <= covered:
            speed, accel = sign * rate, sign * acceleration
            if accel == 0.0:
                return begin + left / speed
            # left = speed*t + accel*t^2/2, the root within the row.
            return begin + (-speed + math.sqrt(max(0.0, speed * speed + 2.0 * accel * left))) \
                / accel
    return rows[-1][0]


def plan_steering(steering: SteeringParameters, gear_rad: float, wheel_rad: float,
                  target_rad: float) -> SteeringMotion:
    """The motion from the gear at ``gear_rad`` and wheels at ``wheel_rad`` to ``target_rad``.

    Instantaneous steering puts the wheels (and the gear) on ``target_rad`` at once.
    """
    if steering.instantaneous:
        return SteeringMotion.still(target_rad)
    end = motor_target(steering, gear_rad, target_rad)
    rows, duration = _gear_profile(gear_rad, end, steering.rate_rad_s,
                                   steering.acceleration_rad_s2)
    gear_knots = np.array(rows)
    if duration == 0.0:
        return SteeringMotion(gear_knots, _still_knots(wheel_rad), 0.0)
    sign = 1.0 if end > gear_rad else -1.0
    half_band = 0.5 * steering.backlash_rad
    # The gear's flank meets the wheels once it has crossed the play on their side.
    engage = sign * (wheel_rad - gear_rad) + half_band
    if engage >= abs(end - gear_rad):
        return SteeringMotion(gear_knots, np.array([[0.0, wheel_rad, 0.0, 0.0],
                                                    [duration, wheel_rad, 0.0, 0.0]]), duration)
    engage_time = _time_travelled(rows, max(0.0, engage), sign)
    wheel_rows = [[0.0, wheel_rad, 0.0, 0.0]] if engage_time > 0.0 else []
    gear_angle, gear_rate = knots_state(gear_knots, engage_time)
    following = [[engage_time, gear_angle - sign * half_band, gear_rate,
                  _acceleration_at(gear_knots, engage_time)]]
    for begin, angle, rate, acceleration in rows:
        if begin > engage_time:
            following.append([begin, angle - sign * half_band, rate, acceleration])
    return SteeringMotion(gear_knots, np.array(wheel_rows + following), duration)


def knots_state(table: np.ndarray, time_s: float) -> tuple[float, float]:
    out = np.empty(2)
    knots.steering_at(float(time_s), table, table.shape[0], out)
    return float(out[0]), float(out[1])


def _acceleration_at(table: np.ndarray, time_s: float) -> float:
    index = int(np.searchsorted(table[:, 0], time_s, side='right')) - 1
    return 0.0 if index >= table.shape[0] - 1 else float(table[max(index, 0), 3])
