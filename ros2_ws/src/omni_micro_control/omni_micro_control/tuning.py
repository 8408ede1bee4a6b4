"""Which of a controller's settings may change while it runs, checked: the controller node's
parameter changes and the fleet twin's per-goal tolerances both go through here (no rclpy)."""

from __future__ import annotations

import dataclasses
from typing import Any

from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import VisionFeedbackController
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.servo_config import SHARED_WITH_SERVO, ServoConfig
from omni_micro_control.servo_session import ServoSession


def reconfigured(config: FeedbackConfig, changes: dict[str, object]) -> FeedbackConfig | str:
    """``config`` with ``changes`` made while the node runs, or why they are refused: section
    4.1's parameters may change, checked first; the mode chose the planner, and the planner holds
    what it has learnt, so it is fixed, as is everything else."""
    fields = FeedbackConfig.__dataclass_fields__
    others = [name for name in changes
              if (name not in fields or name == 'mode') and name != 'use_sim_time']
    if others:
        return f'{others} are fixed while the node runs'
    try:
        return FeedbackConfig(**{**config.__dict__,
                                 **{k: v for k, v in changes.items() if k in fields}})
    except ControllerConfigError as error:
        return str(error)


def servo_reconfigured(config: ServoConfig, changes: dict[str, object]) -> ServoConfig | str:
    """The servo's ``config`` with ``changes`` made while it runs, or why they are refused: the
    settings it shares with the other modes (``SHARED_WITH_SERVO``: a goal's tolerance among
    them) may change, checked first; its own are fixed."""
    fixed = [name for name in changes if name not in (*SHARED_WITH_SERVO, 'use_sim_time')]
    if fixed:
        return (f'{fixed} are fixed while the servo runs (it takes '
                f'{", ".join(SHARED_WITH_SERVO)})')
    # Checked by the config itself, as the node's parameters are at its start.
    changed: dict[str, Any] = {name: value for name, value in changes.items()
                               if name in SHARED_WITH_SERVO}
    try:
        return dataclasses.replace(config, **changed)
    except ControllerConfigError as error:
        return str(error)


def retune(controller: VisionFeedbackController | ServoSession,
           changes: dict[str, object]) -> str | None:
    """Make ``changes`` on ``controller`` while it runs (:func:`reconfigured`, or for the servo
    :func:`servo_reconfigured`); returns why not when they are refused, and nothing changes."""
    if isinstance(controller, ServoSession):
        servo = servo_reconfigured(controller.config, changes)
        if isinstance(servo, str):
            return servo
        controller.servo.config = servo
        return None
    config = reconfigured(controller.config, changes)
    if isinstance(config, str):
        return config
    controller.config = config
    return None
