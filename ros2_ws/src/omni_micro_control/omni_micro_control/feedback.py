"""The vision-feedback method of section 4.1, as a state machine in simulated time.

After each stop the controller waits timer2 for the slip to die out, takes the first capture
stamped after that, turns the robot's wheels toward the goal with the angle modifier
(theta1 = alpha - phi), and lets the distance comparator choose how long the wheels run (timer1:
0.2 s far from the goal, 0.05 s within 2 mm). The paper leaves the end open; here a move that
would overshoot is shortened to land on the goal, and the run finishes within ``tolerance_m`` or
after ``max_periods`` moves.

A run is ``reached`` only when the capture's distance to the goal plus the capture's own 95 %
uncertainty is within the tolerance: an outcome never claims more than the camera can see.
When the seeing camera cannot resolve the tolerance at all, the run ends ``unresolved`` once the
robot is as close as that camera can tell, with the camera's uncertainty in the reason.

Which move to make from a stop is the planner's: :class:`PaperRule` here (section 4.1), or the
model-based planner of :mod:`omni_micro_control.model_based`. The state machine is the same.

Every decision is a function of capture stamps and contents and of the wheel states, never of
when a message happened to arrive, so the same captures give the same moves at any speed.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from typing import Protocol

from omni_micro_control.capture_ages import StatedAges, allowance_words
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.observations import Observation, mean_observation


class Outcome(enum.Enum):
    REACHED = 'reached'        # within tolerance of the goal, uncertainty included
    UNRESOLVED = 'unresolved'  # as close as the seeing camera can tell, coarser than tolerance
    GAVE_UP = 'gave_up'        # max_periods moves and still outside tolerance
    LOST = 'lost'              # no usable capture: robot out of view or camera silent
    COMPLETED = 'completed'    # the open-loop move is done (no feedback, no tolerance)
    CANCELLED = 'cancelled'    # a new goal or a shutdown replaced this one


# Every outcome ends a goal; this is how a status names them.
OUTCOME_NAMES = tuple(outcome.value for outcome in Outcome)
# The reason of the CANCELLED outcome a goal gets when another replaces it (it does not end a
# run: the new goal goes on).
REPLACED_REASON = 'replaced by a new goal'


class Phase(enum.Enum):
    IDLE = 'idle'
    SETTLING = 'settling'      # waiting for timer2 and then a capture
    MOVING = 'moving'          # a move is commanded and the wheels have not stopped yet
    DONE = 'done'


@dataclass(frozen=True)
class MovePlan:
    """What a planner chose: the steering angle, the move's duration, and why."""

    steering_rad: float
    duration_s: float
    rule: str = 'paper'
    note: str = ''


class Planner(Protocol):
    """Chooses each move; learns from each stop if it wants to."""

    def on_stop(self, observation: Observation) -> None: ...

    def plan(self, observation: Observation, goal_m: tuple[float, float],
             config: FeedbackConfig) -> MovePlan: ...


class PaperRule:
    """Section 4.1: the angle modifier theta1 = alpha - phi and the distance comparator."""

    def on_stop(self, observation: Observation) -> None:
        pass

    def plan(self, observation: Observation, goal_m: tuple[float, float],
             config: FeedbackConfig) -> MovePlan:
        dx = goal_m[0] - observation.x_m
        dy = goal_m[1] - observation.y_m
        remaining = math.hypot(dx, dy)
        # Distance comparator: timer1, shortened when a full period would overshoot.
        period = (config.far_period_s if remaining > config.comparator_distance_m
                  else config.near_period_s)
        steering = wrap_angle(math.atan2(dy, dx) - observation.phi_rad)   # angle modifier
        return MovePlan(steering, min(period, remaining / config.speed_m_s))


# Longest a move may take beyond its rolling time before the controller stops waiting for it.
MOVE_ALLOWANCE_S = 2.0


@dataclass(frozen=True)
class Move:
    """Command: at ``start_s`` steer to ``steering_rad`` and run the wheels for ``duration_s``."""

    start_s: float
    steering_rad: float
    duration_s: float
    period: int
    remaining_m: float
    observation: Observation
    rule: str = 'paper'
    note: str = ''


@dataclass(frozen=True)
class Finished:
    outcome: Outcome
    reason: str
    periods: int
    observation: Observation | None


def wrap_angle(angle_rad: float) -> float:
    """The same angle in (-pi, pi]."""
    wrapped = math.remainder(angle_rad, 2.0 * math.pi)
    return math.pi if wrapped == -math.pi else wrapped


class VisionFeedbackController:
    """Section 4.1 for one goal at a time; feed it events, it answers with moves or an end."""

    # Captures that arrive while a move is still running; a few seconds of frames is plenty.
    MAX_EARLY_CAPTURES = 256

    def __init__(self, config: FeedbackConfig | None = None,
                 planner: Planner | None = None) -> None:
        self.config = config or FeedbackConfig()
        self.planner: Planner = planner or PaperRule()
        self._stop_captures: list[Observation] = []
        self.phase = Phase.IDLE
        self.goal_m: tuple[float, float] | None = None
        self.periods = 0
        self.deadline_s = math.inf
        self.tries = 0
        self.last_observation: Observation | None = None
        self._early_captures: list[Observation] = []
        self._blind = False
        self._move_overdue_s = math.inf
        # How late the cameras say their captures come: the timeouts wait that much longer.
        self.capture_ages = StatedAges()

    def set_goal(self, goal_m: tuple[float, float], stopped_at_s: float) -> Finished | None:
        """Aim for ``goal_m`` (platform frame) once the robot has been still since
        ``stopped_at_s``. Returns the end of a goal this one replaces, if any."""
        replaced = None
        if self.phase in (Phase.SETTLING, Phase.MOVING):
            replaced = Finished(Outcome.CANCELLED, REPLACED_REASON, self.periods,
                                self.last_observation)
        self.goal_m = (float(goal_m[0]), float(goal_m[1]))
        self.periods = 0
        self.last_observation = None
        if self.phase is Phase.MOVING:
            return replaced   # the running move ends first; on_wheels_stopped starts timer2
        self._settle_from(stopped_at_s)
        return replaced

    def restart_wait(self, stopped_at_s: float) -> None:
        """The robot's clock turned out to be at ``stopped_at_s``, past timer2's end (this
        controller started late): count timer2 again from there. Earlier stamps change
        nothing, so a controller that was there from time 0 keeps its deadline."""
        if self.phase is Phase.SETTLING and stopped_at_s > self.deadline_s:
            self._settle_from(stopped_at_s)

    def cancel(self, reason: str) -> Finished | None:
        if self.phase in (Phase.IDLE, Phase.DONE):
            return None
        return self._finish(Outcome.CANCELLED, reason)

    def _settle_from(self, stopped_at_s: float) -> None:
        self.phase = Phase.SETTLING
        self.deadline_s = stopped_at_s + self.config.settle_wait_s
        self.tries = 0
        self._blind = False
        self._stop_captures = []

    def _finish(self, outcome: Outcome, reason: str) -> Finished:
        self.phase = Phase.DONE
        return Finished(outcome, reason, self.periods, self.last_observation)

    def on_wheels_stopped(self, stamp_s: float) -> Move | Finished | None:
        """The wheels of the commanded move came to rest at ``stamp_s``: timer2 starts.

        Captures and wheel states come from different nodes, so a capture stamped after timer2
        may arrive before the wheel state that starts timer2: those waiting are decided now.
        """
        if self.phase is not Phase.MOVING:
            return None
        self._settle_from(stamp_s)
        waiting, self._early_captures = self._early_captures, []
        for observation in waiting:
            decision = self.on_capture(observation)
            if decision is not None:
                return decision
        return None

    def on_capture(self, observation: Observation) -> Move | Finished | None:
        """A capture arrived; the first one stamped at or after timer2's end decides."""
        if self.phase is Phase.MOVING:
            if len(self._early_captures) < self.MAX_EARLY_CAPTURES:
                self._early_captures.append(observation)
            return None
        if self.phase is not Phase.SETTLING or observation.stamp_s < self.deadline_s - 1e-9:
            return None
        values = (observation.stamp_s, observation.x_m, observation.y_m, observation.phi_rad)
        if not all(math.isfinite(v) for v in values):
            return None   # a broken capture is as good as none: the timeout will tell
        if self._stop_captures and self._stop_captures[0].camera != observation.camera:
            self._stop_captures = []   # another camera took over: its captures only
        self._stop_captures.append(observation)
        if len(self._stop_captures) < self.config.captures_per_stop:
            return None
        observation = mean_observation(self._stop_captures)
        self._stop_captures = []
        return self._decide(observation)

    def _decide(self, observation: Observation) -> Move | Finished:
        self.last_observation = observation
        self.planner.on_stop(observation)
        assert self.goal_m is not None
        config = self.config
        remaining = math.hypot(self.goal_m[0] - observation.x_m,
                               self.goal_m[1] - observation.y_m)
        camera = f'{observation.camera or "camera"}'
        if observation.count > 1:
            camera += f' ({observation.count} captures)'
        if config.open_loop_duration_s > 0.0 or config.open_loop_to_goal:
            if self.periods >= 1:
                return self._finish(Outcome.COMPLETED, 'open-loop move done')
            steering = wrap_angle(math.atan2(self.goal_m[1] - observation.y_m,
                                             self.goal_m[0] - observation.x_m)
                                  - observation.phi_rad)
            plan = MovePlan(steering, config.open_loop_duration_s
                            or remaining / config.speed_m_s, 'open-loop')
        else:
            seen = observation.radius_95_m
            if remaining + seen <= config.tolerance_m:
                return self._finish(
                    Outcome.REACHED, f'{remaining * 1e6:.2f} um from the goal by the {camera}'
                    f' (+-{seen * 1e6:.2f} um at 95 %)')
            if seen > config.tolerance_m and remaining <= seen:
                return self._finish(
                    Outcome.UNRESOLVED,
                    f'{remaining * 1e6:.2f} um from the goal by the {camera}, whose 95 % '
                    f'uncertainty (+-{seen * 1e6:.2f} um) is coarser than the '
                    f'{config.tolerance_m * 1e6:.2f} um tolerance: as close as it can tell')
            if self.periods >= config.max_periods:
                return self._finish(
                    Outcome.GAVE_UP, f'still {remaining * 1e6:.2f} um from the goal after '
                    f'{self.periods} periods')
            plan = self.planner.plan(observation, self.goal_m, config)
        duration = plan.duration_s
        self.periods += 1
        self.phase = Phase.MOVING
        self._early_captures = []
        # Ramps add at most a second to a move, steering half a turn (realistic preset) a
        # second more; then the same patience as for a capture.
        self._move_overdue_s = (observation.stamp_s + config.command_lead_s + duration
                                + MOVE_ALLOWANCE_S
                                + config.capture_timeout_s * config.max_capture_tries)
        return Move(observation.stamp_s + config.command_lead_s, plan.steering_rad, duration,
                    self.periods, remaining, observation, plan.rule, plan.note)

    def on_foreign_capture(self, reason: str) -> Finished | None:
        """A capture stamped on another clock than the robot's: it would never be current, so
        the goal is lost at once, with ``reason`` (which names both clocks)."""
        if self.phase not in (Phase.SETTLING, Phase.MOVING):
            return None
        return self._finish(Outcome.LOST, reason)

    def on_out_of_field(self, stamp_s: float) -> Finished | None:
        """The camera reports it cannot see the robot: lost once timer2 has run out."""
        if self.phase is not Phase.SETTLING:
            return None
        self._blind = True
        if stamp_s >= self.deadline_s - 1e-9:
            return self._finish(Outcome.LOST, 'the robot is outside every camera field')
        return None

    def take_capture_age(self, camera: str, said: str | None) -> float | None:
        """A tracker's measured age of ``camera``'s captures when it publishes them (its
        status's capture_age_s: ``said``): the capture timeouts count from timer2's end plus
        the oldest any camera has stated, as no capture stamped after timer2 can come sooner.
        Returns that allowance if it grew (None: it did not, or ``said`` is no age)."""
        return self.capture_ages.take(camera, said)

    def on_time(self, now_s: float) -> tuple[int, Finished | None]:
        """Check the capture timeout at simulated time ``now_s``.

        Returns (tries used so far, Finished if the controller gives up on the camera).
        """
        if self.phase is Phase.MOVING and now_s > self._move_overdue_s:
            # The wheels never reported the end of the move: do not wait for ever.
            return self.tries, self._finish(
                Outcome.LOST, 'the wheels did not report the end of the move')
        if self.phase is not Phase.SETTLING:
            return self.tries, None
        if self._blind and now_s >= self.deadline_s - 1e-9:
            return self.tries, self._finish(Outcome.LOST,
                                            'the robot is outside every camera field')
        allowance_s = self.capture_ages.bound_s
        overdue = now_s - self.deadline_s - allowance_s
        tries = int(overdue // self.config.capture_timeout_s) if overdue > 0 else 0
        if tries > self.tries:
            self.tries = tries
            if tries >= self.config.max_capture_tries:
                return tries, self._finish(
                    Outcome.LOST, f'no capture within {tries} x {self.config.capture_timeout_s:g}'
                    f' s{allowance_words(allowance_s)} after the robot stopped')
        return self.tries, None


