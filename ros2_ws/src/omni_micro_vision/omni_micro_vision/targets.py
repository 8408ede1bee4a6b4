"""A chessboard calibration target lying on the platform: where its corners are, and how an
overhead camera sees it.

OpenCV's convention: ``pattern`` counts inner corners (columns x rows), so the board has one
square more each way. Where the target lies is its centre on the platform and the turn of its
rows against the platform's x axis; the square at the board's own lowest x and lowest y is
black. A board whose two counts are both even or both odd looks the same turned half a turn,
so no image can say which way it lies: ``omni-micro calibrate-camera`` refuses it.
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
        columns, rows = self.pattern
        if not (isinstance(columns, int) and isinstance(rows, int) and columns >= 2
                and rows >= 2):
            raise CameraConfigError(f'target pattern must be two whole numbers of inner '
                                    f'corners >= 2 (COLSxROWS), got {self.pattern!r}')
        if not (math.isfinite(self.pitch_m) and self.pitch_m > 0):
            raise CameraConfigError(f'target pitch must be > 0, got {self.pitch_m!r}')
        if not all(math.isfinite(v) for v in (*self.center_m, self.yaw_rad)):
            raise CameraConfigError(f'target centre and yaw must be finite, got '
                                    f'{self.center_m!r}, {self.yaw_rad!r}')

    @property
    def half_turn_symmetric(self) -> bool:
        """Whether the board looks the same turned by half a turn."""
        return (self.pattern[0] + self.pattern[1]) % 2 == 0

    def corners_m(self) -> np.ndarray:
        """The inner corners on the platform, rows x columns x 2: corner [r, c] is c pitches
        along the board's x and r along its y from the corner at its lowest x and y."""
        columns, rows = self.pattern
        along = (np.arange(columns) - (columns - 1) / 2) * self.pitch_m
        across = (np.arange(rows) - (rows - 1) / 2) * self.pitch_m
        bx, by = np.meshgrid(along, across)
        cos, sin = math.cos(self.yaw_rad), math.sin(self.yaw_rad)
        return np.stack([self.center_m[0] + cos * bx - sin * by,
                         self.center_m[1] + sin * bx + cos * by], axis=-1)

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


def render_target(camera: CameraModel, target: Chessboard, yaw_rad: float,
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
