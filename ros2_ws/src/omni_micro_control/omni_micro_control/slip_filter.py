"""Where the rolling robot is and how it is built: an extended Kalman filter over the slip core.

The state is the pose (x, y, heading) and the two assembly offsets xi2 and xi3 that the model
mode identifies after each stop (:mod:`omni_micro_control.model_based`); here they are learnt
from every capture while the robot rolls. With a steering mechanism (``--steering realistic``)
a third: the *steering bias*, how far all three wheels stand off the angle the model has them
at after a steer (the gear's play, which the model knows only as a nominal value); it is
unknown again after every steer. The motion model is the slip core itself
(:class:`omni_micro_sim.simulator.SlipSimulator`), fed the same wheel commands as the robot:
one simulator runs the mean, one more per parameter runs it nudged by ``offset_step_rad``, so
that what each did to the pose since the last capture is their finite difference. The pose's
own Jacobian is exact: the floor is flat and the same everywhere, so a robot turned by dphi at
the last capture would have gone the same way turned about where it was.

What the slip core does not know (a friction it has wrong, a backlash) enters as process noise
that grows with the distance travelled (``travel_noise``, per metre), so that captures keep
pulling the pose back. The velocities are the model's, not states of the filter: they follow
from the wheel commands within milliseconds (the contacts' time constant is ~0.4 ms).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_control.observations import Observation
from omni_micro_control.servo_config import FilterConfig
from omni_micro_sim.parameters import RobotParameters
from omni_micro_sim.profile import WheelSpeedProfile
from omni_micro_sim.simulator import SlipSimulator
from omni_micro_sim.state import RobotState

# The most the filter believes of an offset or of the steering's play (10 deg).
_PARAMETER_LIMIT_RAD = math.radians(10.0)


@dataclass(frozen=True)
class _Command:
    start_s: float
    steering_rad: float
    profile: WheelSpeedProfile


def _with_offsets(robot: RobotParameters, bias: float, xi2: float,
                  xi3: float) -> RobotParameters:
    """``robot`` with offsets xi2, xi3 and all three wheels turned by ``bias``."""
    return robot.replace(wheel_offsets_rad=(robot.wheel_offsets_rad[0] + bias, xi2 + bias,
                                            xi3 + bias))


class SlipFilter:
    """Start it where the robot stands still (a stop's averaged capture), tell it every command
    as it is sent and every capture as it comes; ask it where the robot is at a later time, and
    how it is built."""

    def __init__(self, robot: RobotParameters, start: Observation, steering_rad: float,
                 config: FilterConfig | None = None) -> None:
        self.config = config or FilterConfig()
        self.robot = robot
        # The parameters it learns: the steering bias only with a steering mechanism.
        self._biased = not robot.steering.instantaneous
        xi = robot.wheel_offsets_rad
        self.mean = np.array([start.x_m, start.y_m, start.phi_rad, 0.0, xi[1], xi[2]])
        self.covariance = np.diag(np.full(6, self.config.offset_sigma_rad ** 2))
        self.updates = 0
        self.skipped = 0       # captures older than what the filter had reached
        self.time_s = start.stamp_s
        self._commands: list[_Command] = []
        self._mean_sim = SlipSimulator(self.robot)
        self._nudged: dict[int, SlipSimulator] = {}
        self.restart(start, steering_rad)

    # -- inputs ------------------------------------------------------------------------------
    def command(self, start_s: float, steering_rad: float, profile: WheelSpeedProfile) -> None:
        """A command sent to the robot: steer and run ``profile`` from ``start_s`` on (at once
        if that is not after the filter's time)."""
        if start_s <= self.time_s:
            for simulator in (self._mean_sim, *self._nudged.values()):
                simulator.command(steering_rad, profile)
            return
        self._commands = [c for c in self._commands if c.start_s < start_s]
        self._commands.append(_Command(start_s, steering_rad, profile))

    def update(self, seen: Observation) -> bool:
        """Take a capture into the estimate; False if it was older than the filter's time (two
        cameras' captures can arrive out of order) and was left out."""
        if seen.stamp_s < self.time_s:
            self.skipped += 1
            return False
        start_pose = self._mean_sim.state
        self._advance(seen.stamp_s)
        end = self._mean_sim.state
        travelled = math.hypot(end.x_m - start_pose.x_m, end.y_m - start_pose.y_m)
        # Propagate: the pose's exact Jacobian, and the parameters' by finite difference.
        jacobian = np.eye(6)
        jacobian[0, 2] = -(end.y_m - start_pose.y_m)
        jacobian[1, 2] = end.x_m - start_pose.x_m
        step = self.config.offset_step_rad
        for column, nudged in self._nudged.items():
            moved = nudged.state
            jacobian[0:3, column] = np.array([moved.x_m - end.x_m, moved.y_m - end.y_m,
                                              moved.phi_rad - end.phi_rad]) / step
        noise = np.zeros((6, 6))
        noise[0, 0] = noise[1, 1] = (self.config.travel_noise * travelled) ** 2
        noise[2, 2] = (self.config.heading_noise_rad_per_m * travelled) ** 2
        covariance = jacobian @ self.covariance @ jacobian.T + noise
        predicted = np.array([end.x_m, end.y_m, end.phi_rad])
        # Correct with the capture.
        sigma = (np.array([seen.uncertainty.x_sigma_m, seen.uncertainty.y_sigma_m,
                           seen.uncertainty.heading_sigma_rad])
                 if seen.uncertainty is not None else np.full(3, 1e-9))
        innovation = np.array([seen.x_m, seen.y_m, seen.phi_rad]) - predicted
        innovation[2] = math.remainder(innovation[2], 2.0 * math.pi)
        observed = covariance[0:3, 0:3] + np.diag(sigma ** 2)
        gain = np.linalg.solve(observed, covariance[0:3, :]).T
        correction = gain @ innovation
        self.covariance = (np.eye(6) - gain @ np.eye(3, 6)) @ covariance
        self.mean = np.concatenate([predicted, self.mean[3:]]) + correction
        # A linearisation far from the truth can throw the parameters off: keep them where a
        # robot can be (and the slip core accepts them) until the captures pull them back.
        self.mean[3:] = np.clip(self.mean[3:], -_PARAMETER_LIMIT_RAD, _PARAMETER_LIMIT_RAD)
        self._mean_sim.move_by(*correction[0:3])
        if np.any(correction[3:] != 0.0):
            self._mean_sim = self._mean_sim.with_robot(self._robot_of(self.mean))
        self._restart_sensitivities()
        self.updates += 1
        return True

    def restart(self, start: Observation, steering_rad: float) -> None:
        """The robot at rest (a stop's averaged capture): the pose from the capture, the offsets
        as learnt so far; ``steering_rad``, where gear and wheels stand, counts only before the
        first capture (then the model's own gear and wheels are where its commands left them)."""
        pose_sigma = (np.array([start.uncertainty.x_sigma_m, start.uncertainty.y_sigma_m,
                                start.uncertainty.heading_sigma_rad])
                      if start.uncertainty is not None else np.full(3, 1e-9))
        self.mean[0:3] = (start.x_m, start.y_m, start.phi_rad)
        offsets = self.covariance[4:, 4:].copy()
        self.covariance = np.zeros((6, 6))
        self.covariance[0:3, 0:3] = np.diag(pose_sigma ** 2)
        self.covariance[4:, 4:] = offsets
        # A steer is coming: where the play leaves the wheels is unknown again.
        self.mean[3] = 0.0
        self.covariance[3, 3] = self.config.steering_bias_sigma_rad ** 2 if self._biased \
            else 0.0
        self.time_s = start.stamp_s
        self._commands = []
        if self.updates == 0:
            state = RobotState(x_m=start.x_m, y_m=start.y_m, phi_rad=start.phi_rad)
            self._mean_sim = SlipSimulator(self._robot_of(self.mean), state,
                                           steering_rad=steering_rad)
        else:
            # The same robot at rest, where the capture has it: its gear and wheels stay where
            # its commands left them (a play between them included).
            self._mean_sim = self._mean_sim.with_robot(self._robot_of(self.mean))
            here = self._mean_sim.state
            self._mean_sim.move_by(start.x_m - here.x_m, start.y_m - here.y_m,
                                   math.remainder(start.phi_rad - here.phi_rad, 2.0 * math.pi))
        self._restart_sensitivities()

    # -- what it knows -----------------------------------------------------------------------
    @property
    def robot_estimate(self) -> RobotParameters:
        """The robot with the offsets as estimated now."""
        return self._robot_of(self.mean)

    @property
    def offsets_rad(self) -> tuple[float, float]:
        """xi2 and xi3 as estimated now."""
        return float(self.mean[4]), float(self.mean[5])

    @property
    def wheels_steering_rad(self) -> float:
        """Where the model has the wheels' steering now (a gear's play leaves them off the
        commanded angle)."""
        return self._mean_sim.steering_rad

    @property
    def gear_rad(self) -> float:
        """Where the model has the steering gear now."""
        return self._mean_sim.gear_rad

    def state_at(self, time_s: float) -> RobotState:
        """Where the model has the robot at ``time_s`` (not before the filter's time), through
        the commands sent so far."""
        ahead = self._mean_sim.with_robot(self._mean_sim.params)
        self._run(ahead, self.time_s, time_s)
        return ahead.state

    # -- internals ---------------------------------------------------------------------------
    def _robot_of(self, mean: np.ndarray) -> RobotParameters:
        return _with_offsets(self.robot, float(mean[3]), float(mean[4]), float(mean[5]))

    def _restart_sensitivities(self) -> None:
        step = self.config.offset_step_rad
        self._nudged = {}
        for index in (3, 4, 5) if self._biased else (4, 5):
            nudged = self.mean.copy()
            nudged[index] += step
            self._nudged[index] = self._mean_sim.with_robot(self._robot_of(nudged))

    def _advance(self, time_s: float) -> None:
        for simulator in (self._mean_sim, *self._nudged.values()):
            self._run(simulator, self.time_s, time_s)
        self.time_s = time_s
        self._commands = [c for c in self._commands if c.start_s > time_s]

    def _run(self, simulator: SlipSimulator, from_s: float, to_s: float) -> None:
        """Step ``simulator`` from ``from_s`` to ``to_s``, switching to each pending command at
        its start (a later command replaces what runs, as on the robot)."""
        now = from_s
        for command in self._commands:
            if command.start_s > to_s:
                break
            if command.start_s > now:
                simulator.step(command.start_s - now)
                now = command.start_s
            simulator.command(command.steering_rad, command.profile)
        if to_s > now:
            simulator.step(to_s - now)
