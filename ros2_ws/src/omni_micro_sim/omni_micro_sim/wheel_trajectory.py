"""The wheel command contract, independent of the message classes.

A command is a trajectory_msgs/JointTrajectory over :data:`JOINT_NAMES` (any order):

* ``header.stamp``: the simulated time at which the move starts (zero: as soon as it arrives);
* every point has ``time_from_start`` (s, strictly increasing, the first 0), ``positions`` with
  the steering angle (rad, the same at every point: steering is set once, before the wheels turn)
  and the wheel rotations since the start (rad), and ``velocities`` with the wheel spin speeds
  (rad/s, linear in between, the last all zero so that the robot ends at rest);
* no points at all: stop now (the wheels ramp down at the motors' deceleration);
* at most :data:`MAX_POINTS` points (a move has four: 10,000 once slowed the robot's node
  from 50 ticks a second to one), the steering angle within +-2 pi (beyond that a float no
  longer holds the angle to a fraction of a turn: 1e20 rad is no direction at all).

:func:`command_from_points` checks a received command and :func:`points_from_profile` builds
one; the nodes only move numbers between these and the messages.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from omni_micro_common.conventions import JOINT_NAMES
from omni_micro_sim.errors import CommandError
from omni_micro_sim.parameters import MotorLimits
from omni_micro_sim.profile import WHEEL_COUNT, WheelCommand, WheelSpeedProfile

MAX_POINTS = 1000
MAX_STEERING_RAD = 2.0 * math.pi


@dataclass(frozen=True)
class TrajectoryPoint:
    time_from_start_s: float
    positions: Sequence[float]
    velocities: Sequence[float]


def points_from_profile(steering_rad: float,
                        profile: WheelSpeedProfile) -> list[TrajectoryPoint]:
    """The points of a command running ``profile`` along ``steering_rad``, in JOINT_NAMES order."""
    points = []
    for time_s, speeds in zip(profile.knot_times_s, profile.knot_speeds_rad_s,
                                  strict=True):
        rotation = profile.rotation_until(float(time_s))
        points.append(TrajectoryPoint(float(time_s), [steering_rad, *map(float, rotation)],
                                      [0.0, *map(float, speeds)]))
    return points


def command_from_points(joint_names: Sequence[str], points: Sequence[TrajectoryPoint],
                        start_s: float, now_s: float, limits: MotorLimits) -> WheelCommand:
    """Check a received trajectory and turn it into a command; raise CommandError saying why not.

    ``start_s`` <= 0 means "now" (``now_s``).
    """
    names = list(joint_names)
    if sorted(names) != sorted(JOINT_NAMES) or len(set(names)) != len(names):
        raise CommandError(f'joint names must be {list(JOINT_NAMES)} in any order, got {names}')
    if not math.isfinite(start_s):
        raise CommandError(f'start stamp must be finite, got {start_s!r}')
    start = now_s if start_s <= 0.0 else start_s
    if not points:
        return WheelCommand(start_s=now_s)
    if len(points) > MAX_POINTS:
        raise CommandError(f'a trajectory of {len(points)} points: at most {MAX_POINTS}')
    order = [names.index(name) for name in JOINT_NAMES]
    times = np.empty(len(points))
    speeds = np.empty((len(points), WHEEL_COUNT))
    steering = None
    for index, point in enumerate(points):
        if len(point.positions) != len(names) or len(point.velocities) != len(names):
            raise CommandError(
                f'point {index} must have {len(names)} positions and velocities, got '
                f'{len(point.positions)} and {len(point.velocities)}')
        positions = np.asarray(point.positions, dtype=np.float64)[order]
        velocities = np.asarray(point.velocities, dtype=np.float64)[order]
        values = np.concatenate(([point.time_from_start_s], positions, velocities))
        if not np.all(np.isfinite(values)):
            raise CommandError(f'point {index} has a non-finite value: {values.tolist()}')
        if steering is None:
            steering = float(positions[0])
            if abs(steering) > MAX_STEERING_RAD:
                raise CommandError(f'steering angle {steering!r} rad: expected within +-2 pi '
                                   f'(+-{MAX_STEERING_RAD:.4f} rad)')
        elif positions[0] != steering:
            raise CommandError(
                f'steering must stay {steering!r} rad for the whole move, point {index} has '
                f'{float(positions[0])!r}')
        times[index] = point.time_from_start_s
        speeds[index] = velocities[1:]
    if times[0] != 0.0:
        raise CommandError(f'the first point must be at time_from_start 0, got {times[0]!r} s')
    if np.any(np.diff(times) <= 0.0):
        raise CommandError(f'time_from_start must increase strictly, got {times.tolist()}')
    if np.any(speeds[-1] != 0.0):
        raise CommandError(
            f'the last point must stop every wheel (velocities 0), got {speeds[-1].tolist()}')
    assert steering is not None   # points is not empty
    profile = WheelSpeedProfile(times, speeds)
    profile.check_limits(limits)
    return WheelCommand(start_s=start, steering_rad=steering, profile=profile)
