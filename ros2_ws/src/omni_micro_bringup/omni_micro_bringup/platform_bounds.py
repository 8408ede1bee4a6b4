"""The platform rectangle goals must lie in, read from the controller's params as it will be."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.params_files import params_from_files


def controller_parameter(name: str, params_files: tuple[Path, ...]) -> Any:
    """A controller_node parameter as the node will see it: package file, then --params."""
    return params_from_files('controller_node', *params_files).get(name)


def check_goal(goal_m: tuple[float, float], params_files: tuple[Path, ...]) -> None:
    """Refuse a goal outside the platform before anything starts (exit 2, nothing written)."""
    from omni_micro_control.platform import checked_platform

    center = controller_parameter('platform.center_m', params_files)
    size = controller_parameter('platform.size_m', params_files)
    checked_platform(list(center), list(size))   # as the node will: a size of 0 is no platform
    x, y = goal_m
    if abs(x - center[0]) > size[0] / 2 or abs(y - center[1]) > size[1] / 2:
        raise UsageError(
            f'goal ({x * 1e3:g}, {y * 1e3:g}) mm is outside the platform: x in '
            f'[{(center[0] - size[0] / 2) * 1e3:g}, {(center[0] + size[0] / 2) * 1e3:g}] mm, y in '
            f'[{(center[1] - size[1] / 2) * 1e3:g}, {(center[1] + size[1] / 2) * 1e3:g}] mm')
