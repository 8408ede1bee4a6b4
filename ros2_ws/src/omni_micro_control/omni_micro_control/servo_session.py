"""The servo (:mod:`omni_micro_control.servo`) as the controller node and the twin both drive it:
one goal after another, the wheels' stop read from their states, a goal's end as the other
modes end theirs (:class:`omni_micro_control.feedback.Finished`, its periods the moves). No
rclpy: the node only turns messages into these calls, so the twin and the graph are one
behaviour.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from omni_micro_control.capture_ages import StatedAges
from omni_micro_control.feedback import REPLACED_REASON, Finished, Outcome, Phase
from omni_micro_control.observations import Observation
from omni_micro_control.servo_config import ServoCommand, ServoConfig, ServoPhase
from omni_micro_sim.parameters import MotorLimits, RobotParameters

if TYPE_CHECKING:
    from omni_micro_control.servo import ServoController

OUT_OF_FIELD_REASON = 'the robot is outside every camera field'


class ServoSession:
    """Feed it the wheel states, the stationary captures, the captures in motion and what the
    cameras say; it answers with commands and, at a goal's end, a Finished."""

    def __init__(self, config: ServoConfig, limits: MotorLimits, robot: RobotParameters) -> None:
        # Here, not above: a controller node of another mode imports this module and must not
        # load the slip core the servo plans through.
        from omni_micro_control.servo import ServoController

        self.servo: ServoController = ServoController(config, limits, robot)
        self.captures_in_motion = 0
        self.capture_ages = StatedAges(config.capture_age_s)

    @property
    def config(self) -> ServoConfig:
        return self.servo.config

    @property
    def goal_m(self) -> tuple[float, float] | None:
        return self.servo.goal_m

    @property
    def phase(self) -> Phase:
        """As the other modes name it: done, moving (rolling) or settling (at a stop)."""
        return {ServoPhase.DONE: Phase.DONE, ServoPhase.ROLLING: Phase.MOVING}.get(
            self.servo.phase, Phase.SETTLING)

    def set_goal(self, goal_m: tuple[float, float], stopped_at_s: float) -> Finished | None:
        """Aim for ``goal_m``; returns the end of a goal this one replaces, if any (the robot
        finishes the running command, and the new goal's first stop starts it)."""
        replaced = None
        if self.servo.phase is not ServoPhase.DONE:
            replaced = Finished(Outcome.CANCELLED, REPLACED_REASON, self.servo.moves, None)
        self.servo.set_goal(goal_m, stopped_at_s)
        return replaced

    def restart_wait(self, stopped_at_s: float) -> None:
        """This node started late: the settling counts from ``stopped_at_s``."""
        if self.servo.phase is ServoPhase.SETTLING and self.servo.goal_m is not None:
            self.servo.set_goal(self.servo.goal_m, stopped_at_s)

    def on_wheel_state(self, stamp_s: float, speeds_rad_s: Sequence[float]) -> None:
        """The command is over once its profile has ended and every wheel stands (a steering
        motion stops the wheels mid-command: that is no end)."""
        command = self.servo.command
        if command is not None and not any(speeds_rad_s) \
                and stamp_s >= command.start_s + command.profile.end_time_s:
            self.servo.on_wheels_stopped(stamp_s)

    def on_capture(self, seen: Observation) -> ServoCommand | Finished | None:
        return self.servo.on_capture(seen) if _finite(seen) else None

    def on_capture_in_motion(self, seen: Observation) -> ServoCommand | None:
        """A capture of the rolling robot; a broken one (not finite) is as good as none."""
        if not _finite(seen):
            return None
        self.captures_in_motion += 1
        return self.servo.on_capture_in_motion(seen)

    def take_capture_age(self, camera: str, said: str | None) -> float | None:
        """A tracker's measured age of ``camera``'s captures in motion when it publishes them
        (its status's capture_age_s, in seconds: ``said``): the servo starts its corrections no
        sooner after a capture's stamp than the oldest any camera has stated, nor than its own
        setting. Returns the new bound if it grew (None: it did not, or ``said`` is no age)."""
        bound = self.capture_ages.take(camera, said)
        if bound is not None:
            self.servo.config = dataclasses.replace(self.servo.config, capture_age_s=bound)
        return bound

    def on_out_of_field(self, stamp_s: float) -> Finished | None:
        """The camera cannot see the robot: lost, unless the goal is over."""
        return self._finish(Outcome.LOST, OUT_OF_FIELD_REASON)

    def on_foreign_capture(self, reason: str) -> Finished | None:
        """A capture on another clock than the robot's: lost at once, with ``reason``."""
        return self._finish(Outcome.LOST, reason)

    def cancel(self, reason: str) -> Finished | None:
        return self._finish(Outcome.CANCELLED, reason)

    def _finish(self, outcome: Outcome, reason: str) -> Finished | None:
        if self.servo.phase is ServoPhase.DONE:
            return None
        self.servo.phase = ServoPhase.DONE
        return Finished(outcome, reason, self.servo.moves, None)


def _finite(seen: Observation) -> bool:
    return all(math.isfinite(v) for v in (seen.stamp_s, seen.x_m, seen.y_m, seen.phi_rad))
