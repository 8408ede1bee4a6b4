"""The model-based mode: plan each move through the slip core, learn the robot as it goes.

The paper's rule steers as if the robot did not slip and corrects the drift afterwards in short
moves. This mode instead shoots through the slip model: from the latest stop it finds the
steering angle and the move's duration (any length) whose predicted stop is the goal. After
every move it refits the robot's unknown parameters (the assembly offsets xi2 and xi3 by
default) to every stop seen so far (:mod:`omni_micro_control.identification`), starting from
nominal values, so that each plan uses what the moves so far have shown.

It never trusts the model blindly. When a stop misses the plan's prediction by more than the
uncertainty of the start capture and of the parameters allows, the refit cannot absorb it: its
chi-square (prior included) grows by more than the 99.9 % quantile of 3 degrees of freedom
(one stop's x, y and heading). The next period then falls back to the paper's rule, and says
so. (A linear propagation of the parameters' spread would not do: the first move's drift of
several millimetres is far from linear in the offsets' prior range.)
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_control.chains import Chain, RecordedMove, SteeringTracker, Stop
from omni_micro_control.errors import ControllerConfigError, IdentificationError
from omni_micro_control.feedback import MovePlan, PaperRule, VisionFeedbackController, wrap_angle
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.identification import (
    OFFSETS,
    PARAMETERS,
    Prior,
    compose,
    displacement,
    fit_parameters,
)
from omni_micro_control.observations import Observation
from omni_micro_control.servo_session import ServoSession
from omni_micro_sim.errors import CommandError, SimulationError
from omni_micro_sim.parameters import MotorLimits, RobotParameters
from omni_micro_sim.profile import move_profile

# chi-square with 3 degrees of freedom at 99.9 %: a stop this unlikely means the model is wrong.
MISS_THRESHOLD = 16.266


@dataclass(frozen=True)
class ModelConfig:
    """What the model-based mode learns and how far it trusts itself.

    ``free_parameters`` are names of :data:`omni_micro_control.identification.PARAMETERS`;
    ``prior_sigma_rad`` is the spread of the offsets before any move (the nominal robot has
    none); ``max_chain_moves`` bounds the refit's cost: older stops are folded into the prior.
    """

    free_parameters: tuple[str, ...] = OFFSETS
    prior_sigma_rad: float = math.radians(3.0)
    max_chain_moves: int = 8
    max_shooting_iterations: int = 12
    shooting_tolerance_m: float = 1e-10

    def __post_init__(self) -> None:
        names = tuple(self.free_parameters)
        unknown = [name for name in names if name not in PARAMETERS]
        if unknown or not names:
            raise ControllerConfigError(
                f'model.free_parameters must be some of {sorted(PARAMETERS)}, got {list(names)}')
        object.__setattr__(self, 'free_parameters', names)
        if not (math.isfinite(self.prior_sigma_rad) and self.prior_sigma_rad > 0.0):
            raise ControllerConfigError(
                f'model.prior_sigma_rad must be a finite number > 0, got {self.prior_sigma_rad!r}')
        for name in ('max_chain_moves', 'max_shooting_iterations'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ControllerConfigError(
                    f'model.{name} must be a whole number >= 1, got {value!r}')


@dataclass
class PlannerLog:
    """What the planner did, for the node's log and the studies."""

    plan_wall_s: list[float] = field(default_factory=list)
    fit_wall_s: list[float] = field(default_factory=list)
    fallbacks: list[str] = field(default_factory=list)
    estimates: list[dict[str, float]] = field(default_factory=list)


def stop_from(observation: Observation) -> Stop:
    uncertainty = observation.uncertainty or CaptureUncertainty(1e-9, 1e-9, 1e-9)
    return Stop(observation.x_m, observation.y_m, observation.phi_rad, uncertainty,
                observation.stamp_s, observation.camera)


class ModelBasedPlanner:
    """Plans moves by shooting through the slip core and refits the robot after each stop.

    Parameters
    ----------
    robot : the nominal robot: every parameter the model does not fit is taken as it is here,
        and the fitted ones start from its values.
    limits : the motors (the move profile).
    config : see :class:`ModelConfig`.
    """

    def __init__(self, robot: RobotParameters | None = None, limits: MotorLimits | None = None,
                 config: ModelConfig | None = None) -> None:
        self.config = config or ModelConfig()
        self.limits = limits or MotorLimits()
        self.nominal = robot or RobotParameters()
        self.robot = self.nominal
        self.names = self.config.free_parameters
        # With a steering motion the planner steers through the preset's model from where its
        # own commands left the gear, and learns the gear's backlash with the offsets.
        self.tracker: SteeringTracker | None = None
        if not self.nominal.steering.instantaneous:
            self.tracker = SteeringTracker(self.nominal.steering)
            if 'backlash' not in self.names:
                self.names = (*self.names, 'backlash')
        self.prior = Prior(self._values(),
                           np.diag([self._prior_sigma(name) ** 2 for name in self.names]))
        self.covariance = self.prior.covariance.copy()
        self.chain = Chain()
        self._pending: tuple[Stop, RecordedMove, np.ndarray] | None = None
        self._cost = 0.0   # the chain's fit cost so far (0: a new chain sits on its prior)
        self._fallback_next = ''
        self._paper = PaperRule()
        self.log = PlannerLog()

    def _prior_sigma(self, name: str) -> float:
        return (self.config.prior_sigma_rad if name in OFFSETS
                else PARAMETERS[name].prior_sigma)

    # -- learning ---------------------------------------------------------------------------
    def estimate(self) -> dict[str, float]:
        """The current estimate of each free parameter (SI), with ``<name>_sigma``."""
        values: dict[str, float] = {}
        for index, name in enumerate(self.names):
            values[name] = PARAMETERS[name].get(self.robot)
            values[f'{name}_sigma'] = float(math.sqrt(self.covariance[index, index]))
        return values

    def on_stop(self, observation: Observation) -> None:
        """A stop decided a period (or ended the goal): learn from the move that led there."""
        stop = stop_from(observation)
        pending, self._pending = self._pending, None
        if pending is None or not self.chain.stops or self.chain.stops[-1] is not pending[0]:
            # The first stop, or one not reached by our last move (a new goal after a
            # cancelled move): a new chain, keeping what was learnt as the prior.
            self._restart_chain(stop)
            return
        _, move, predicted = pending
        self.chain.stops.append(stop)
        self.chain.moves.append(move)
        began = time.perf_counter()
        try:
            fit = fit_parameters([self.chain], self.nominal, self.names, self.prior,
                                 initial=self._values())
        except (IdentificationError, np.linalg.LinAlgError, SimulationError) as error:
            self._fallback(f'the refit failed ({error})')
            self._restart_chain(stop)
            return
        finally:
            self.log.fit_wall_s.append(time.perf_counter() - began)
        growth = fit.cost - self._cost
        if growth > MISS_THRESHOLD:
            miss = math.hypot(*(stop.pose[:2] - predicted[:2]))
            self._fallback(f"the stop was {miss * 1e6:.2f} um from the model's prediction, "
                           f'more than its uncertainty allows (chi-square +{growth:.1f})')
            # Whatever went wrong, do not let it bend the estimate: start a new chain here.
            self._restart_chain(stop)
            return
        self.robot = fit.robot
        self._cost = fit.cost
        # The prior counts in the fit: its covariance is the posterior (not widened, since a
        # real robot's extra scatter is what the fallback check is for).
        self.covariance = fit.covariance / max(1.0, fit.reduced_chi_square)
        self.log.estimates.append(self.estimate())
        if len(self.chain.moves) >= self.config.max_chain_moves:
            self._restart_chain(stop)

    def _fallback(self, reason: str) -> None:
        self._fallback_next = reason
        self.log.fallbacks.append(reason)

    def _values(self) -> np.ndarray:
        return np.array([PARAMETERS[name].get(self.robot) for name in self.names])

    def _restart_chain(self, stop: Stop) -> None:
        """A new chain from ``stop``; what the old one taught becomes its prior."""
        self.prior = Prior(self._values(), self.covariance.copy())
        self.chain = Chain([stop], [])
        self._cost = 0.0

    # -- planning ---------------------------------------------------------------------------
    def plan(self, observation: Observation, goal_m: tuple[float, float],
             config: FeedbackConfig) -> MovePlan:
        """The move from ``observation`` (the stop just seen) that should end on ``goal_m``."""
        began = time.perf_counter()
        stop = self.chain.stops[-1] if self.chain.stops else stop_from(observation)
        try:
            plan = self._plan_from(stop, observation, goal_m, config)
            profile = move_profile(plan.duration_s, self.limits)
            move = (RecordedMove(plan.steering_rad, profile) if self.tracker is None
                    else self.tracker.move(plan.steering_rad, profile))
            # Whichever rule planned it, the move is data: the next stop links to it.
            self._pending = (stop, move, self._predict(stop, move))
            return plan
        finally:
            self.log.plan_wall_s.append(time.perf_counter() - began)

    def _plan_from(self, stop: Stop, observation: Observation, goal_m: tuple[float, float],
                   config: FeedbackConfig) -> MovePlan:
        if self._fallback_next:
            reason, self._fallback_next = self._fallback_next, ''
            plan = self._paper.plan(observation, goal_m, config)
            return MovePlan(plan.steering_rad, plan.duration_s, 'paper',
                            f"{reason}: the paper's rule for this period")
        try:
            steering, duration, iterations = self._shoot(stop.pose, goal_m, config)
        except (CommandError, SimulationError, np.linalg.LinAlgError) as error:
            plan = self._paper.plan(observation, goal_m, config)
            return MovePlan(plan.steering_rad, plan.duration_s, 'paper',
                            f"no model plan ({error}): the paper's rule for this period")
        return MovePlan(steering, duration, 'model',
                        f'shot in {iterations} iterations; {self._estimate_text()}')

    def _estimate_text(self) -> str:
        parts = []
        for index, name in enumerate(self.names):
            spec = PARAMETERS[name]
            value = spec.get(self.robot) * spec.display_scale
            sigma = math.sqrt(self.covariance[index, index]) * spec.display_scale
            parts.append(f'{spec.label} {value:.3f} +- {sigma:.3f} {spec.unit}'.rstrip())
        return ', '.join(parts)

    def _shoot(self, pose: np.ndarray, goal_m: tuple[float, float],
               config: FeedbackConfig) -> tuple[float, float, int]:
        """Newton's method on (steering, duration) so that the predicted stop is the goal."""
        goal = np.array(goal_m, dtype=np.float64)
        offset = goal - pose[:2]
        cos_phi, sin_phi = math.cos(pose[2]), math.sin(pose[2])
        body = np.array([cos_phi * offset[0] + sin_phi * offset[1],
                         -sin_phi * offset[0] + cos_phi * offset[1]])
        unknowns = np.array([math.atan2(body[1], body[0]),
                             float(np.hypot(*body)) / config.speed_m_s])

        robot = self.robot
        gear_path: tuple[float, ...] = ()
        if self.tracker is not None:
            gear_path = tuple(self.tracker.gear_path)
            # Whole motor steps would make the miss a staircase in the angle: the shooting
            # steers continuously and the next period takes up the rounding.
            robot = robot.replace(steering=robot.steering.replace(step_rad=0.0))

        def miss(values: np.ndarray) -> np.ndarray:
            move = RecordedMove(float(values[0]), move_profile(float(values[1]), self.limits),
                                gear_path)
            return compose(pose, displacement(robot, move))[:2] - goal

        error = miss(unknowns)
        for iteration in range(1, self.config.max_shooting_iterations + 1):
            if float(np.hypot(*error)) <= self.config.shooting_tolerance_m:
                return wrap_angle(float(unknowns[0])), float(unknowns[1]), iteration - 1
            steps = np.array([1e-7, max(unknowns[1] * 1e-6, 1e-10)])
            jacobian = np.column_stack([
                (miss(unknowns + np.eye(2)[k] * steps[k]) - error) / steps[k] for k in range(2)])
            step = -np.linalg.solve(jacobian, error)
            scale = 1.0
            while True:
                candidate = unknowns + scale * step
                if candidate[1] > 0.0:
                    trial = miss(candidate)
                    if np.hypot(*trial) < np.hypot(*error) or scale < 1e-3:
                        break
                scale *= 0.5
                if scale < 1e-6:
                    raise CommandError('the shooting found no move toward the goal')
            unknowns, error = candidate, trial
        if float(np.hypot(*error)) > max(1e-8, self.config.shooting_tolerance_m):
            raise CommandError(f'the shooting still misses by {np.hypot(*error) * 1e6:.3f} um '
                               f'after {self.config.max_shooting_iterations} iterations')
        return (wrap_angle(float(unknowns[0])), float(unknowns[1]),
                self.config.max_shooting_iterations)

    def _predict(self, stop: Stop, move: RecordedMove) -> np.ndarray:
        """The stop ``move`` leads to from ``stop`` by the current model."""
        return compose(stop.pose, displacement(self.robot, move))

def planner_for(config: FeedbackConfig, robot: RobotParameters | None = None,
                limits: MotorLimits | None = None,
                model: ModelConfig | None = None) -> PaperRule | ModelBasedPlanner:
    """The planner of ``config.mode``: the node and the in-process twin both build it here."""
    if config.mode == 'model':
        return ModelBasedPlanner(robot, limits, model)
    if config.mode != 'paper':
        raise ControllerConfigError(f'the {config.mode} mode plans no stop-and-go moves: '
                                    f'omni_micro_control.servo_session drives it')
    return PaperRule()


def learnt_offsets(controller: VisionFeedbackController | ServoSession
                   ) -> tuple[float, float] | None:
    """The wheel offsets xi2, xi3 (rad) as the model mode or the servo has learnt them so far;
    None for the paper's rule, or before the servo's first move."""
    if isinstance(controller, ServoSession):
        estimate = controller.servo.filter
        return estimate.offsets_rad if estimate is not None else None
    if isinstance(controller.planner, ModelBasedPlanner):
        robot = controller.planner.robot   # its offsets as fitted, or as given if not fitted
        return robot.wheel_offsets_rad[1], robot.wheel_offsets_rad[2]
    return None
