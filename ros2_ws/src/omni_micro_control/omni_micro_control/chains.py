"""What the identification reads: chains of stops that a camera saw, linked by the moves commanded
between them, and where the steering gear stood for each move."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_control.errors import IdentificationError
from omni_micro_sim.parameters import SteeringParameters
from omni_micro_sim.profile import WheelSpeedProfile


@dataclass(frozen=True)
class Stop:
    """Where the robot stood still, as a camera saw it (possibly the mean of several frames)."""

    x_m: float
    y_m: float
    phi_rad: float
    uncertainty: CaptureUncertainty
    stamp_s: float = 0.0
    camera: str = ''

    @property
    def pose(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m, self.phi_rad])

    @property
    def sigmas(self) -> np.ndarray:
        u = self.uncertainty
        return np.array([u.x_sigma_m, u.y_sigma_m, u.heading_sigma_rad])


@dataclass(frozen=True)
class RecordedMove:
    """A commanded move: the steering angle and the wheels' speed profile.

    With a steering motion the move starts by steering from where the gear stood, as the
    commands put it (:class:`SteeringTracker`): ``gear_path`` holds every angle the gear
    stood at since the wheels were centred in the backlash, the last one where this move
    starts. Where in the play the wheels are follows from that path and the backlash
    (:func:`wheels_after`). An empty path: the wheels stand at ``steering_rad`` already (the
    paper's moves).
    """

    steering_rad: float
    profile: WheelSpeedProfile
    gear_path: tuple[float, ...] = ()


def wheels_after(gear_path: Sequence[float], backlash_rad: float) -> float:
    """The wheels' angle after the gear went through ``gear_path`` from the first angle with
    the wheels centred: the play (backlash) operator, the gear's flanks dragging the wheels."""
    half_band = 0.5 * backlash_rad
    wheels = gear_path[0]
    for gear in gear_path[1:]:
        wheels = min(max(wheels, gear - half_band), gear + half_band)
    return wheels


class SteeringTracker:
    """Where the steering gear stands after each commanded angle, as the robot moves it
    (:func:`omni_micro_sim.steering.motor_target`); starts at ``gear_rad``, wheels centred."""

    def __init__(self, steering: SteeringParameters, gear_rad: float = 0.0) -> None:
        self.steering = steering
        self.gear_path = [gear_rad]
        self._target: float | None = gear_rad
        self.steering_time_s = 0.0   # of the last move: the motor's, whatever the backlash

    def move(self, steering_rad: float, profile: WheelSpeedProfile) -> RecordedMove:
        """The move commanding ``steering_rad``, with the steering it starts from; the gear
        then stands where that command leaves it."""
        from omni_micro_sim.steering import motor_target, plan_steering

        move = RecordedMove(steering_rad, profile, tuple(self.gear_path))
        self.steering_time_s = 0.0
        if steering_rad != self._target:   # the robot steers no further for the same angle
            self.steering_time_s = plan_steering(self.steering, self.gear_rad, self.gear_rad,
                                                 steering_rad).duration_s
            target = motor_target(self.steering, self.gear_rad, steering_rad)
            if target != self.gear_rad:
                self.gear_path.append(target)
            self._target = steering_rad
        return move

    @property
    def gear_rad(self) -> float:
        return self.gear_path[-1]


@dataclass
class Chain:
    """Stops linked by moves: ``stops[i + 1]`` is where ``moves[i]`` from ``stops[i]`` ended."""

    stops: list[Stop] = field(default_factory=list)
    moves: list[RecordedMove] = field(default_factory=list)

    def __post_init__(self) -> None:
        if self.stops and len(self.stops) != len(self.moves) + 1:
            raise IdentificationError(
                f'a chain of {len(self.moves)} moves needs {len(self.moves) + 1} stops, '
                f'got {len(self.stops)}')
