"""Simulated time on a fixed grid, with wheel commands that start at a stamped simulated time.

:class:`GridSimulator` is what the dynamics node (and the in-process closed-loop runner) drive:
time advances in whole periods, every period is integrated the same way whatever the real-time
factor, and a command starts at the first grid time at or after its stamp. A command therefore
runs for exactly its profile in simulated time, however late its message arrived; a late
command starts at the current grid time, and the lateness is reported, not hidden.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim.errors import CommandError
from omni_micro_sim.parameters import (
    DEFAULT_PERIOD_S,
    MotorLimits,
    RobotParameters,
    require_finite,
)
from omni_micro_sim.profile import WheelCommand, move_profile
from omni_micro_sim.simulator import (
    ContactSlip,
    MotionStatus,
    SlipSimulator,
)
from omni_micro_sim.state import RobotState


@dataclass(frozen=True)
class Sample:
    """Everything the robot publishes at one grid time."""

    time_s: float
    state: RobotState
    steering_rad: float
    steering_rate_rad_s: float
    wheel_rotations_rad: np.ndarray
    wheel_speeds_rad_s: np.ndarray
    slip: ContactSlip
    status: MotionStatus


@dataclass(frozen=True)
class Scheduled:
    """Where a command landed on the grid, and how long its stamp had passed when it came."""

    start_s: float
    late_by_s: float


class GridSimulator:
    """A :class:`SlipSimulator` advanced in whole ``period_s`` steps, with scheduled commands."""

    def __init__(self, params: RobotParameters, *, period_s: float = DEFAULT_PERIOD_S,
                 limits: MotorLimits | None = None, state: RobotState | None = None) -> None:
        period = require_finite('period_s', period_s)
        if period <= 0.0:
            raise CommandError(f'period_s must be > 0, got {period_s!r}')
        self.period_s = period
        self.limits = limits or MotorLimits()
        self.simulator = SlipSimulator(params, state)
        self._tick = 0
        self._pending: tuple[int, WheelCommand] | None = None

    @property
    def tick(self) -> int:
        return self._tick

    @property
    def time_s(self) -> float:
        return self._tick * self.period_s

    @property
    def pending(self) -> WheelCommand | None:
        return None if self._pending is None else self._pending[1]

    def schedule(self, command: WheelCommand) -> Scheduled:
        """Queue ``command`` (replacing one still waiting) and say when it will start.

        A stop is never delayed: it takes effect at the current grid time.

        Raises
        ------
        CommandError
            If the steering angle or start time is not finite, or the profile breaks the motor
            limits; nothing is queued then.
        """
        try:
            require_finite('steering angle', command.steering_rad)
            start = require_finite('start time', command.start_s)
        except ValueError as error:
            raise CommandError(str(error)) from None
        if command.profile is not None:
            command.profile.check_limits(self.limits)
        if command.is_stop:
            start = self.time_s
        # A hair of tolerance so that a stamp computed as k * period lands on tick k.
        start_tick = max(math.ceil(start / self.period_s - 1e-9), self._tick)
        self._pending = (start_tick, command)
        # Late means the stamp had passed on arrival; rounding up to the grid is not lateness.
        return Scheduled(start_tick * self.period_s, max(0.0, self.time_s - start))

    def schedule_stop(self) -> None:
        """Ramp the wheels down from the current grid time (cannot fail)."""
        self.schedule(WheelCommand(start_s=self.time_s))

    def sample(self) -> Sample:
        simulator = self.simulator
        return Sample(self.time_s, simulator.state, simulator.steering_rad,
                      simulator.steering_rate_rad_s, simulator.wheel_rotations_rad(),
                      simulator.wheel_speeds(), simulator.slip(), simulator.status)

    def load_kernels(self) -> None:
        """Integrate a period on a copy, leaving this one as it was: the first call of each
        compiled kernel loads it from numba's cache (about half a second), which is better spent
        before time starts than in the first tick of a run. A move too: its profile is typed
        differently from standing still."""
        trial = copy.deepcopy(self)
        trial.schedule(WheelCommand(start_s=trial.time_s, profile=move_profile(self.period_s)))
        trial.advance()
        trial.advance()

    def advance(self) -> Sample:
        """Start a due command, integrate one period and return the sample at its end."""
        if self._pending is not None and self._pending[0] <= self._tick:
            command = self._pending[1]
            self._pending = None
            if command.profile is None:   # a stop
                self.simulator.stop(self.limits)
            else:
                self.simulator.command(command.steering_rad, command.profile, self.limits)
        self.simulator.step(self.period_s)
        self._tick += 1
        return self.sample()


def load_default_kernels() -> None:
    """Load, once in this process, the kernels a robot of the paper's parameters runs on (see
    :meth:`GridSimulator.load_kernels`): a process that forks nodes does it for all of them."""
    GridSimulator(RobotParameters()).load_kernels()
