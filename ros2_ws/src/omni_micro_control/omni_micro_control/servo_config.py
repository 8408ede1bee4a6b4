"""The servo's settings, commands and phases (no rclpy, and none of the slip core: a controller
node of another mode reads them without loading the physics): :mod:`omni_micro_control.servo`
plans with them, :mod:`omni_micro_control.slip_filter` estimates with its part.
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass, field

from omni_micro_common.conventions import GOAL_TOLERANCE_M
from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback_config import MODEL_CAPTURES_PER_STOP, FeedbackConfig
from omni_micro_sim.parameters import DEFAULT_PERIOD_S
from omni_micro_sim.profile import WheelSpeedProfile

# FeedbackConfig's mode of a controller that runs the servo.
SERVO_MODE = 'servo'
# ServoConfig fields that are the controller's own parameters, shared with the other modes.
SHARED_WITH_SERVO = ('tolerance_m', 'settle_wait_s', 'captures_per_stop')


@dataclass(frozen=True)
class FilterConfig:
    """How sure the filter is of the robot before the captures, and of its own motion model."""

    offset_sigma_rad: float = math.radians(3.0)    # as the model mode's prior
    steering_bias_sigma_rad: float = math.radians(1.0)   # the play's range, after a steer
    offset_step_rad: float = 1.0e-4                 # finite difference of the offsets
    travel_noise: float = 2.0e-3                    # position error per metre travelled (1 sigma)
    heading_noise_rad_per_m: float = 0.05           # heading error per metre travelled (1 sigma)

    def __post_init__(self) -> None:
        for name in ('offset_sigma_rad', 'steering_bias_sigma_rad', 'offset_step_rad',
                     'travel_noise',
                     'heading_noise_rad_per_m'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ControllerConfigError(f'{name} must be a number > 0, got {value!r}')


@dataclass(frozen=True)
class ServoConfig:
    """The servo's settings (SI). The tolerance, the settling and the captures per stop are the
    controller's own, shared with the other modes (the same parameters)."""

    tolerance_m: float = GOAL_TOLERANCE_M
    crawl_speed_rad_s: float = 0.5
    crawl_m: float = 2.0e-4
    freeze_steering_m: float = 1.0e-5
    replan_period_s: float = 0.1
    # Its own, shorter than the stop-and-go modes': every 20 ms of lead is 17 um the crawl
    # rolls on an older estimate (measured on Fig. 11: 0.02 s stops within 0.3 um, 0.05 s
    # within 0.45 um and needs a second move for a 0.5 um tolerance).
    command_lead_s: float = 0.02
    # The oldest a capture in motion is when it arrives: the graph's bringup and the twin set it
    # from the cameras' timings (capture_age_bound_s); this default covers theirs.
    capture_age_s: float = 0.05
    # The robot starts a command on its next tick: the dynamics' period (the bringup and the twin
    # set it from theirs).
    command_period_s: float = DEFAULT_PERIOD_S
    settle_wait_s: float = FeedbackConfig.settle_wait_s
    captures_per_stop: int = MODEL_CAPTURES_PER_STOP
    max_moves: int = 10
    shooting_iterations: int = 4
    shooting_tolerance_m: float = 1.0e-9
    filter: FilterConfig = field(default_factory=FilterConfig)

    def __post_init__(self) -> None:
        for name in ('tolerance_m', 'crawl_speed_rad_s', 'crawl_m', 'replan_period_s',
                     'shooting_tolerance_m', 'command_period_s'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ControllerConfigError(f'{name} must be a number > 0, got {value!r}')
        for name in ('freeze_steering_m', 'command_lead_s', 'capture_age_s', 'settle_wait_s'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ControllerConfigError(f'{name} must be a number >= 0, got {value!r}')
        for name in ('captures_per_stop', 'max_moves', 'shooting_iterations'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ControllerConfigError(f'{name} must be a whole number >= 1, got {value!r}')


@dataclass(frozen=True)
class ServoCommand:
    """Steer to ``steering_rad`` and run ``profile`` from ``start_s`` (what ran is replaced);
    ``from_rest``: a move from a stop, else a plan made again while rolling."""

    start_s: float
    steering_rad: float
    profile: WheelSpeedProfile
    from_rest: bool = True


class ServoPhase(enum.Enum):
    ROLLING = 'rolling'
    SETTLING = 'settling'
    CAPTURING = 'capturing'
    DONE = 'done'
