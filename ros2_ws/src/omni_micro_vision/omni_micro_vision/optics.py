"""A simulated camera's mount and lens: what they do to the ideal image the renderer draws.

:func:`omni_micro_vision.rendering.render` draws the platform as an ideal camera square to
its own frame sees it (turned by the mount's yaw). A real camera may also show it mirrored (a
mirror in the optics, a driver's flip) and through a lens that distorts (plumb_bob: k1, k2).
:class:`CameraOptics` applies both with OpenCV (a flip and one ``remap``), and gives the
CameraInfo a driver of that camera would publish (K, D, R, P). Its :attr:`plane` is the true
map from the frame's pixels to the platform: what a calibration should find. No rclpy.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from omni_micro_vision.camera import CameraModel
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import Lens, PlaneMap

# How far each camera's lens is from the platform: with the pixel on the platform it sets the
# focal length in pixels (K) of a pinhole camera. A 16 mm lens at 0.3 m for the macro camera,
# a long-working-distance microscope objective for the micro one.
WORKING_DISTANCE_M = {'macro': 0.3, 'micro': 0.04}


@dataclass(frozen=True)
class CameraOptics:
    """A camera's mount and lens. ``distortion`` is (k1, k2), radial, in the normalised image
    coordinates of K."""

    camera: CameraModel
    yaw_rad: float = 0.0
    mirrored: bool = False
    working_distance_m: float = 0.3
    distortion: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.working_distance_m) and self.working_distance_m > 0):
            raise CameraConfigError(f'{self.camera.name}.working_distance_m must be > 0, got '
                                    f'{self.working_distance_m!r}')
        values = list(self.distortion)
        if len(values) != 2 or not all(isinstance(v, (int, float)) and math.isfinite(v)
                                       and abs(v) <= 1.0 for v in values):
            raise CameraConfigError(f'{self.camera.name}.distortion must be [k1, k2], each '
                                    f'within +-1, got {self.distortion!r}')
        object.__setattr__(self, 'distortion', (float(values[0]), float(values[1])))
        if not isinstance(self.mirrored, bool):
            raise CameraConfigError(f'{self.camera.name}.mirrored must be true or false, got '
                                    f'{self.mirrored!r}')
        # The lens must not fold the image onto itself inside the frame (r grows with r_d).
        columns, rows = self.camera.resolution_px
        matrix = np.array(self.lens.camera_matrix).reshape(3, 3)
        corner = math.hypot((columns / 2) / matrix[0, 0], (rows / 2) / matrix[1, 1])
        radii = np.linspace(0.0, corner, 200)
        k1, k2 = self.distortion
        if np.any(np.diff(radii * (1 + k1 * radii ** 2 + k2 * radii ** 4)) <= 0):
            raise CameraConfigError(f'{self.camera.name}.distortion {list(self.distortion)} '
                                    'folds the image within the frame')

    @property
    def lens(self) -> Lens:
        """K of a pinhole at the working distance (pixels as wide and high as on the
        platform), D (plumb_bob) with the radial terms."""
        columns, rows = self.camera.resolution_px
        px, py = self.camera.pixel_size_m
        fx, fy = self.working_distance_m / px, self.working_distance_m / py
        return Lens((fx, 0.0, (columns - 1) / 2, 0.0, fy, (rows - 1) / 2, 0.0, 0.0, 1.0),
                    (*self.distortion, 0.0, 0.0, 0.0))

    @functools.cached_property
    def plane(self) -> PlaneMap:
        """The true map from this camera's frames to the platform."""
        return PlaneMap.nominal(self.camera, self.yaw_rad, self.mirrored, self.lens)

    @functools.cached_property
    def _remap(self) -> tuple[np.ndarray, np.ndarray] | None:
        """For each pixel of the frame, where it lies in the ideal image (None: nowhere else)."""
        if not self.lens.distorts:
            return None
        columns, rows = (int(v) for v in self.camera.resolution_px)
        grid = np.stack(np.meshgrid(np.arange(columns, dtype=np.float64),
                                    np.arange(rows, dtype=np.float64)), axis=-1)
        ideal = self.lens.undistorted(grid.reshape(-1, 2)).reshape(rows, columns, 2)
        return (np.ascontiguousarray(ideal[..., 0], np.float32),
                np.ascontiguousarray(ideal[..., 1], np.float32))

    def prepare(self) -> None:
        """Compute the lens's map now (0.2-0.5 s for a megapixel), not at the first frame."""
        _ = self._remap

    def view(self, ideal: np.ndarray) -> np.ndarray:
        """The frame this camera takes of ``ideal`` (the renderer's image, in the camera's own
        frame): flipped left to right if mirrored, then through the lens."""
        image = ideal[:, ::-1] if self.mirrored else ideal
        maps = self._remap
        if maps is None:
            return np.ascontiguousarray(image)
        import cv2

        viewed: np.ndarray = cv2.remap(np.ascontiguousarray(image), maps[0], maps[1],
                                       cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return viewed
