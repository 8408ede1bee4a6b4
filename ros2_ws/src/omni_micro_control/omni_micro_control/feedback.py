"""The vision-feedback method of section 4.1, as a state machine in simulated time.

After each stop the controller waits timer2 for the slip to die out, takes the first capture
stamped after that, turns the robot's wheels toward the goal with the angle modifier
(theta1 = alpha - phi), and lets the distance comparator choose how long the wheels run (timer1:
0.2 s far from the goal, 0.05 s within 2 mm). The paper leaves the end open; here a move that
would overshoot is shortened to land on the goal, and the run finishes within ``tolerance_m`` or
after ``max_periods`` moves.

Every decision is a function of capture stamps and contents and of the wheel states, never of
when a message happened to arrive, so the same captures give the same moves at any speed.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass


class ControllerConfigError(ValueError):
    """A controller parameter is out of range; the message names it."""


class Outcome(enum.Enum):
    REACHED = 'reached'        # within tolerance of the goal
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


def _number(name: str, value: float, *, minimum: float | None = None,
            strictly: bool = True) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ControllerConfigError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number):
        raise ControllerConfigError(f'{name} must be finite, got {value!r}')
    if minimum is not None and (number <= minimum if strictly else number < minimum):
        raise ControllerConfigError(
            f'{name} must be {">" if strictly else ">="} {minimum:g}, got {value!r}')
    return number


@dataclass(frozen=True)
class FeedbackConfig:
    """Timers and thresholds of section 4.1 plus the end rule the paper leaves open.

    ``wheel_radius_m`` and ``cruise_speed_rad_s`` convert between a move's duration t and the
    distance its wheels roll (r * cruise * t, section 3.5).
    """

    settle_wait_s: float = 0.1            # timer2
    far_period_s: float = 0.2             # timer1 beyond the comparator distance
    near_period_s: float = 0.05           # timer1 within it
    comparator_distance_m: float = 2.0e-3
    tolerance_m: float = 3.0e-6
    max_periods: int = 100
    command_lead_s: float = 0.05          # a move starts this long after its capture's stamp
    open_loop_duration_s: float = 0.0     # > 0: one move of this long, no feedback
    capture_timeout_s: float = 1.0        # wait this long for a capture before trying again
    max_capture_tries: int = 3
    wheel_radius_m: float = 1.65e-3
    cruise_speed_rad_s: float = 8.7

    def __post_init__(self) -> None:
        for name in ('far_period_s', 'near_period_s', 'comparator_distance_m', 'tolerance_m',
                     'capture_timeout_s', 'wheel_radius_m', 'cruise_speed_rad_s'):
            object.__setattr__(self, name, _number(name, getattr(self, name), minimum=0.0))
        for name in ('settle_wait_s', 'command_lead_s', 'open_loop_duration_s'):
            object.__setattr__(self, name, _number(name, getattr(self, name), minimum=0.0,
                                                   strictly=False))
        for name in ('max_periods', 'max_capture_tries'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ControllerConfigError(f'{name} must be a whole number >= 1, got {value!r}')

    @property
    def speed_m_s(self) -> float:
        """Ground speed of a slip-free robot at cruise wheel speed."""
        return self.wheel_radius_m * self.cruise_speed_rad_s


@dataclass(frozen=True)
class Observation:
    """A capture as the controller sees it (any camera that follows the contract)."""

    stamp_s: float
    x_m: float
    y_m: float
    phi_rad: float
    camera: str = ''


@dataclass(frozen=True)
class Move:
    """Command: at ``start_s`` steer to ``steering_rad`` and run the wheels for ``duration_s``."""

    start_s: float
    steering_rad: float
    duration_s: float
    period: int
    remaining_m: float
    observation: Observation


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

    def __init__(self, config: FeedbackConfig | None = None) -> None:
        self.config = config or FeedbackConfig()
        self.phase = Phase.IDLE
        self.goal_m: tuple[float, float] | None = None
        self.periods = 0
        self.deadline_s = math.inf
        self.tries = 0
        self.last_observation: Observation | None = None
        self._early_captures: list[Observation] = []
        self._blind = False
        self._move_overdue_s = math.inf

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
        self.last_observation = observation
        assert self.goal_m is not None
        config = self.config
        dx = self.goal_m[0] - observation.x_m
        dy = self.goal_m[1] - observation.y_m
        remaining = math.hypot(dx, dy)
        if config.open_loop_duration_s > 0.0:
            if self.periods >= 1:
                return self._finish(Outcome.COMPLETED, 'open-loop move done')
            duration = config.open_loop_duration_s
        else:
            if remaining <= config.tolerance_m:
                return self._finish(
                    Outcome.REACHED, f'{remaining * 1e6:.2f} um from the goal by the '
                    f'{observation.camera or "camera"}')
            if self.periods >= config.max_periods:
                return self._finish(
                    Outcome.GAVE_UP, f'still {remaining * 1e6:.2f} um from the goal after '
                    f'{self.periods} periods')
            # Distance comparator: timer1, shortened when a full period would overshoot.
            period = (config.far_period_s if remaining > config.comparator_distance_m
                      else config.near_period_s)
            duration = min(period, remaining / config.speed_m_s)
        alpha = math.atan2(dy, dx)
        steering = wrap_angle(alpha - observation.phi_rad)   # angle modifier
        self.periods += 1
        self.phase = Phase.MOVING
        self._early_captures = []
        # Ramps add at most a second to a move; then the same patience as for a capture.
        self._move_overdue_s = (observation.stamp_s + config.command_lead_s + duration + 1.0
                                + config.capture_timeout_s * config.max_capture_tries)
        return Move(observation.stamp_s + config.command_lead_s, steering, duration,
                    self.periods, remaining, observation)

    def on_out_of_field(self, stamp_s: float) -> Finished | None:
        """The camera reports it cannot see the robot: lost once timer2 has run out."""
        if self.phase is not Phase.SETTLING:
            return None
        self._blind = True
        if stamp_s >= self.deadline_s - 1e-9:
            return self._finish(Outcome.LOST, 'the robot is outside every camera field')
        return None

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
        overdue = now_s - self.deadline_s
        tries = int(overdue // self.config.capture_timeout_s) if overdue > 0 else 0
        if tries > self.tries:
            self.tries = tries
            if tries >= self.config.max_capture_tries:
                return tries, self._finish(
                    Outcome.LOST, f'no capture within {tries} x '
                    f'{self.config.capture_timeout_s:g} s after the robot stopped')
        return self.tries, None


class MoveWatcher:
    """Tells from the wheel joint states when a commanded move is over.

    The move is over at the first state in which the driven wheel has turned by the commanded
    rotation since the command and stands still. Wheel 2 is watched: it is always driven (wheel 1
    may be passive and roll freely).
    """

    WATCHED_WHEEL = 1

    def __init__(self) -> None:
        self._baseline_rad: float | None = None
        self._target_rad = 0.0
        self.latest_rotations: tuple[float, ...] | None = None

    @property
    def watching(self) -> bool:
        return self._baseline_rad is not None

    def expect(self, rotation_rad: float) -> None:
        """A move that turns each wheel by ``rotation_rad`` was just commanded."""
        if self.latest_rotations is None:
            raise RuntimeError('no wheel state received yet; cannot watch a move')
        self._baseline_rad = self.latest_rotations[self.WATCHED_WHEEL]
        self._target_rad = abs(rotation_rad)

    def forget(self) -> None:
        self._baseline_rad = None

    def on_wheel_state(self, rotations_rad: tuple[float, ...],
                       speeds_rad_s: tuple[float, ...]) -> bool:
        """Feed one wheel state (three wheels); True once, when the watched move is over."""
        self.latest_rotations = tuple(rotations_rad)
        if self._baseline_rad is None:
            return False
        turned = abs(rotations_rad[self.WATCHED_WHEEL] - self._baseline_rad)
        # The receiver rebuilds the profile from nanosecond stamps, so the rotation it reports
        # can differ from the commanded one in the ninth digit.
        if (turned >= self._target_rad * (1.0 - 1e-6)
                and speeds_rad_s[self.WATCHED_WHEEL] == 0.0
                and speeds_rad_s[2] == 0.0):
            self._baseline_rad = None
            return True
        return False
