"""Calibration targets lying on the platform: where their points are, and how an overhead
camera sees them.

Two kinds, in OpenCV's conventions. A chessboard: ``pattern`` counts inner corners (columns x
rows), the board has one square more each way, and the square at its own lowest x and lowest y
is black. An asymmetric circle grid (``findCirclesGrid`` with ``CALIB_CB_ASYMMETRIC_GRID``):
``pattern`` counts circles per row and rows, circle (row i, column j) at ``((2 j + i % 2) p,
i p)`` for the pitch p; dark circles on white. Where a target lies is its centre on the platform
and the turn of its rows against the platform's x axis. A chessboard whose two counts are both
even or both odd, and a circle grid with an even number of rows, look the same turned half a
turn, so no image can say which way they lie: ``omni-micro calibrate-camera`` refuses them.
No rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_vision.camera import CameraModel, camera_frame
from omni_micro_vision.errors import CameraConfigError

BLACK_LEVEL = 0.05
WHITE_LEVEL = 0.85
# The printed board's white border, in squares: OpenCV finds a board by its outer squares.
QUIET_ZONE_SQUARES = 1.0


@dataclass(frozen=True)
class Chessboard:
    """``pattern`` (columns, rows) of inner corners, ``pitch_m`` a square's side, lying with
    its centre at ``center_m`` and its rows turned ``yaw_rad`` from the platform's x."""

    pattern: tuple[int, int]
    pitch_m: float
    center_m: tuple[float, float]
    yaw_rad: float = 0.0

    def __post_init__(self) -> None:
        _check(self)

    kind = 'chessboard'

    @property
    def half_turn_symmetric(self) -> bool:
        """Whether the board looks the same turned by half a turn."""
        return (self.pattern[0] + self.pattern[1]) % 2 == 0

    def points_m(self) -> np.ndarray:
        """The inner corners on the platform, rows x columns x 2: corner [r, c] is c pitches
        along the board's x and r along its y from the corner at its lowest x and y."""
        columns, rows = self.pattern
        along = (np.arange(columns) - (columns - 1) / 2) * self.pitch_m
        across = (np.arange(rows) - (rows - 1) / 2) * self.pitch_m
        bx, by = np.meshgrid(along, across)
        return _on_platform(self, bx, by)

    def reflectance(self, x_m: np.ndarray, y_m: np.ndarray,
                    platform_level: float) -> np.ndarray:
        """What fraction of the light the platform points (x, y) send back."""
        cos, sin = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        dx, dy = x_m - self.center_m[0], y_m - self.center_m[1]
        bx, by = cos * dx + sin * dy, -sin * dx + cos * dy   # in the board's frame
        columns, rows = self.pattern
        i = np.floor(bx / self.pitch_m + (columns + 1) / 2)
        j = np.floor(by / self.pitch_m + (rows + 1) / 2)
        on_board = (i >= 0) & (i <= columns) & (j >= 0) & (j <= rows)
        result = np.where(on_board & ((i + j) % 2 == 0), BLACK_LEVEL, WHITE_LEVEL)
        margin = QUIET_ZONE_SQUARES
        on_paper = ((np.abs(bx) <= ((columns + 1) / 2 + margin) * self.pitch_m)
                    & (np.abs(by) <= ((rows + 1) / 2 + margin) * self.pitch_m))
        return np.where(on_paper, result, platform_level)


@dataclass(frozen=True)
class CircleGrid:
    """An asymmetric grid of ``pattern`` (circles per row, rows) dark circles, ``pitch_m``
    apart as OpenCV counts it, lying with its centre at ``center_m`` and its rows turned
    ``yaw_rad`` from the platform's x."""

    pattern: tuple[int, int]
    pitch_m: float
    center_m: tuple[float, float]
    yaw_rad: float = 0.0

    kind = 'circles'
    # A circle's radius in pitches: neighbours in a row are two pitches apart, the nearest
    # ones in the next row sqrt(2).
    RADIUS_PITCHES = 0.35

    def __post_init__(self) -> None:
        _check(self)

    @property
    def half_turn_symmetric(self) -> bool:
        return self.pattern[1] % 2 == 0

    def _grid(self) -> tuple[np.ndarray, np.ndarray]:
        """Each circle's centre in the grid's own frame (x along its rows), from its middle."""
        columns, rows = self.pattern
        j, i = np.meshgrid(np.arange(columns), np.arange(rows))
        gx, gy = (2 * j + i % 2) * self.pitch_m, i * self.pitch_m
        return gx - (2 * columns - 1) * self.pitch_m / 2, gy - (rows - 1) * self.pitch_m / 2

    def points_m(self) -> np.ndarray:
        """The circles' centres on the platform, rows x columns x 2, in OpenCV's order."""
        return _on_platform(self, *self._grid())

    def reflectance(self, x_m: np.ndarray, y_m: np.ndarray,
                    platform_level: float) -> np.ndarray:
        cos, sin = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        dx, dy = x_m - self.center_m[0], y_m - self.center_m[1]
        bx, by = cos * dx + sin * dy, -sin * dx + cos * dy
        columns, rows = self.pattern
        p = self.pitch_m
        # From the grid's first circle: a point is only ever near one row (the rows are a pitch
        # apart, a circle 0.35 across), and in it near one circle.
        ox, oy = bx + (2 * columns - 1) * p / 2, by + (rows - 1) * p / 2
        i = np.clip(np.round(oy / p), 0, rows - 1)
        j = np.clip(np.round((ox / p - i % 2) / 2), 0, columns - 1)
        inside = np.hypot(ox - (2 * j + i % 2) * p, oy - i * p) <= self.RADIUS_PITCHES * p
        margin = 2 * p
        on_paper = ((np.abs(bx) <= (2 * columns - 1) * p / 2 + margin)
                    & (np.abs(by) <= (rows - 1) * p / 2 + margin))
        return np.where(on_paper, np.where(inside, BLACK_LEVEL, WHITE_LEVEL), platform_level)


Target = Chessboard | CircleGrid


def _check(target: Target) -> None:
    columns, rows = target.pattern
    if not (isinstance(columns, int) and isinstance(rows, int) and columns >= 2 and rows >= 2):
        raise CameraConfigError(f'target pattern must be two whole numbers >= 2 (COLSxROWS), '
                                f'got {target.pattern!r}')
    if not (math.isfinite(target.pitch_m) and target.pitch_m > 0):
        raise CameraConfigError(f'target pitch must be > 0, got {target.pitch_m!r}')
    if not all(math.isfinite(v) for v in (*target.center_m, target.yaw_rad)):
        raise CameraConfigError(f'target centre and yaw must be finite, got '
                                f'{target.center_m!r}, {target.yaw_rad!r}')
TARGET_KINDS: dict[str, type[Chessboard] | type[CircleGrid]] = {'chessboard': Chessboard,
                                                              'circles': CircleGrid}


def _on_platform(target: Target, bx: np.ndarray, by: np.ndarray) -> np.ndarray:
    cos, sin = math.cos(target.yaw_rad), math.sin(target.yaw_rad)
    return np.stack([target.center_m[0] + cos * bx - sin * by,
                     target.center_m[1] + sin * bx + cos * by], axis=-1)


def render_target(camera: CameraModel, target: Target, yaw_rad: float,
                  supersample: int = 4) -> np.ndarray:
    """The target's reflectance as ``camera`` turned by ``yaw_rad`` sees it in its own frame
    (rows x columns, float32; the renderer's convention: row 0 the largest y), each pixel the
    mean of ``supersample`` x ``supersample`` points over its area."""
    from omni_micro_vision.fiducial import PLATFORM_LEVEL
    from omni_micro_vision.rendering import pixel_centres

    xs, ys = pixel_centres(camera)
    px, py = camera.pixel_size_m
    offsets = (np.arange(supersample) + 0.5) / supersample - 0.5
    total = np.zeros((ys.size, xs.size), np.float64)
    for du in offsets:
        for dv in offsets:
            cx, cy = np.meshgrid(xs + du * px, ys - dv * py)
            # Points of the camera's frame back on the platform.
            x, y, _ = camera_frame(camera, -yaw_rad, cx, cy, 0.0)
            total += target.reflectance(np.asarray(x), np.asarray(y), PLATFORM_LEVEL)
    result: np.ndarray = (total / supersample ** 2).astype(np.float32)
    return result


# A target for the micro camera, on its field's centre: 9 x 6 inner corners of 0.15 mm squares
# (1.8 x 1.35 mm with its white border, in the 2 mm field). The macro camera wants ~10 mm ones.
DEFAULT_TARGET = Chessboard((9, 6), 0.15e-3, (0.1, 0.0))
