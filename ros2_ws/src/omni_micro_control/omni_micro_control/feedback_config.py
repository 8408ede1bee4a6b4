"""The settings of section 4.1's controller (its timers and thresholds, the end rule the paper
leaves open), checked as they are made, and the controller modes: what
:mod:`omni_micro_control.feedback` runs with, and what the servo shares of it. No rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from omni_micro_common.conventions import GOAL_TOLERANCE_M
from omni_micro_control.errors import ControllerConfigError
from omni_micro_sim.parameters import MotorLimits, RobotParameters

# Controller modes: who plans each move. The servo keeps the robot rolling between one stop at
# the start and one at the end (omni_micro_control.servo_session); it shares this config's
# tolerance, settling and captures per stop, and plans with its own (servo_config).
MODES = ('paper', 'model', 'servo')
# Five frames (0.13 s at 30 Hz) shrink a capture's spread by sqrt(5): the micro camera's 95 %
# radius goes from 0.35 um to 0.16 um, so a 0.5 um tolerance is met after one fine move.
MODEL_CAPTURES_PER_STOP = 5

# The longest open-loop move: the paper's is 7 s (100 mm); a minute runs off any platform.
MAX_OPEN_LOOP_S = 60.0


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
    tolerance_m: float = GOAL_TOLERANCE_M
    max_periods: int = 100
    command_lead_s: float = 0.05          # a move starts this long after its capture's stamp
    open_loop_duration_s: float = 0.0     # > 0: one move of this long, no feedback
    open_loop_to_goal: bool = False       # one move of the nominal time to the goal, no feedback
    capture_timeout_s: float = 1.0        # wait this long for a capture before trying again
    max_capture_tries: int = 3
    # The robot's and its motors' own (omni_micro_sim.parameters), defined there once.
    wheel_radius_m: float = RobotParameters.wheel_radius_m
    cruise_speed_rad_s: float = MotorLimits.cruise_speed_rad_s
    mode: str = 'paper'                   # 'paper' (section 4.1), 'model' or 'servo' (MODES)
    # Average this many captures of each stop; 0 = the mode's own: 1 for the paper's rule
    # (section 4.1 takes one), MODEL_CAPTURES_PER_STOP for the model and the servo, whose plans
    # are only as good as the start pose they shoot from.
    captures_per_stop: int = 0

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ControllerConfigError(f'mode must be one of {list(MODES)}, got {self.mode!r}')
        for name in ('far_period_s', 'near_period_s', 'comparator_distance_m', 'tolerance_m',
                     'capture_timeout_s', 'wheel_radius_m', 'cruise_speed_rad_s'):
            object.__setattr__(self, name, _number(name, getattr(self, name), minimum=0.0))
        for name in ('settle_wait_s', 'command_lead_s', 'open_loop_duration_s'):
            object.__setattr__(self, name, _number(name, getattr(self, name), minimum=0.0,
                                                   strictly=False))
        if self.open_loop_duration_s > MAX_OPEN_LOOP_S:
            raise ControllerConfigError(
                f'open_loop_duration_s must be at most {MAX_OPEN_LOOP_S:g} s (at cruise speed '
                f'{MAX_OPEN_LOOP_S * self.speed_m_s * 1e3:.0f} mm, past any platform), got '
                f'{self.open_loop_duration_s!r}')
        if not isinstance(self.open_loop_to_goal, bool) or \
                (self.open_loop_to_goal and self.open_loop_duration_s > 0.0):
            raise ControllerConfigError(f'open_loop_to_goal must be true or false, and false '
                                        f'with an open_loop_duration_s, got '
                                        f'{self.open_loop_to_goal!r}')
        if self.captures_per_stop == 0:
            object.__setattr__(self, 'captures_per_stop',
                               1 if self.mode == 'paper' else MODEL_CAPTURES_PER_STOP)
        for name in ('max_periods', 'max_capture_tries', 'captures_per_stop'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ControllerConfigError(f'{name} must be a whole number >= 1, got {value!r}')

    @property
    def speed_m_s(self) -> float:
        """Ground speed of a slip-free robot at cruise wheel speed."""
        return self.wheel_radius_m * self.cruise_speed_rad_s
