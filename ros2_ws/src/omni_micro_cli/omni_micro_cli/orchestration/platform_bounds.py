"""The platform rectangle goals must lie in, read from the controller's params as it will be."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from omni_micro_cli.errors import UsageError
from omni_micro_cli.orchestration.graph import package_params_file


def controller_parameter(name: str, params_file: Path | None) -> Any:
    """A controller_node parameter as the node will see it: package file, then --params."""
    value: Any = None
    files = [package_params_file('omni_micro_control', 'controller_node')]
    if params_file is not None:
        files.append(params_file)
    for path in files:
        content = yaml.safe_load(path.read_text()) or {}
        for node in ('controller_node', '/**'):
            params = (content.get(node) or {}).get('ros__parameters') or {}
            node_value: Any = params
            for part in name.split('.'):
                node_value = node_value.get(part) if isinstance(node_value, dict) else None
            if node_value is not None:
                value = node_value
    return value


def check_goal(goal_m: tuple[float, float], params_file: Path | None) -> None:
    """Refuse a goal outside the platform before anything starts (exit 2, nothing written)."""
    center = controller_parameter('platform.center_m', params_file)
    size = controller_parameter('platform.size_m', params_file)
    x, y = goal_m
    if abs(x - center[0]) > size[0] / 2 or abs(y - center[1]) > size[1] / 2:
        raise UsageError(
            f'goal ({x * 1e3:g}, {y * 1e3:g}) mm is outside the platform: x in '
            f'[{(center[0] - size[0] / 2) * 1e3:g}, {(center[0] + size[0] / 2) * 1e3:g}] mm, y in '
            f'[{(center[1] - size[1] / 2) * 1e3:g}, {(center[1] + size[1] / 2) * 1e3:g}] mm')
