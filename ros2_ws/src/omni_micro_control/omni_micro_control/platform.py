"""The platform a goal must lie on: its rectangle, checked, and why a goal is refused.

No rclpy: ``controller_node`` and the command line (which refuses a goal before anything
starts) read the platform the same way.
"""

from __future__ import annotations

import math

from omni_micro_control.errors import ControllerConfigError


def checked_platform(center: list[float], size: list[float]) -> None:
    """The platform goals must lie on: a centre and a size, two finite numbers each, the size
    > 0 (a platform of [0, 0] took every goal for outside it, or none).

    Raises
    ------
    ControllerConfigError
        Naming the value.
    """
    for name, values, positive in (('platform.center_m', center, False),
                                   ('platform.size_m', size, True)):
        if len(values) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v)
                                       and (v > 0 or not positive) for v in values):
            raise ControllerConfigError(f'{name} must be two finite numbers'
                                        f'{" > 0" if positive else ""} (metres), got '
                                        f'{list(values)}')


def goal_error(x_m: float, y_m: float, center: list[float], size: list[float]) -> str | None:
    """Why a goal cannot be accepted, or None."""
    if not (math.isfinite(x_m) and math.isfinite(y_m)):
        return f'goal ({x_m!r}, {y_m!r}) m is not finite'
    if abs(x_m - center[0]) > size[0] / 2 or abs(y_m - center[1]) > size[1] / 2:
        return (f'goal ({x_m * 1e3:.3f}, {y_m * 1e3:.3f}) mm is outside the platform '
                f'(centre {center[0] * 1e3:g}, {center[1] * 1e3:g} mm, '
                f'{size[0] * 1e3:g} x {size[1] * 1e3:g} mm)')
    return None
