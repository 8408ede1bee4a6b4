"""Which of a controller's settings may change while it runs, checked: the controller node's
parameter changes and the fleet twin's per-goal tolerances both go through here (no rclpy)."""

from __future__ import annotations

from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import FeedbackConfig


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
