"""Where a camera's pixels lie on the platform: its lens, as CameraInfo carries it, and a
homography from the undistorted image to the platform plane.

A camera looking down at a plane sees it through one homography once the lens distortion is
taken out (image_pipeline's view: K and D from the driver's CameraInfo, ``plumb_bob``). Pixel
coordinates are OpenCV's and ROS's: the centre of the top-left pixel is (0, 0), u to the right,
v down. A camera looking down maps (u, v) to the platform's (x, y) with a negative determinant
(its v axis is the platform's -y); a mirrored image (a mirror in the optics, or a driver's flip)
has a positive one.

:meth:`PlaneMap.nominal` is an ideal camera of a given field, resolution, turn and mirror (what
``camera_node`` renders, and what ``tracker_node`` assumes without a calibration);
``omni-micro calibrate-camera`` fits a real one from frames of a target
(:mod:`omni_micro_vision.calibration`). No rclpy.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from omni_micro_vision.camera import CameraModel, check_resolution
from omni_micro_vision.errors import CameraConfigError

UNCALIBRATED_K = (0.0,) * 9


def _numbers(name: str, values: object) -> tuple[float, ...]:
    try:
        numbers = tuple(float(v) for v in values)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise CameraConfigError(f'{name} must be a list of numbers, got {values!r}') from None
    if not all(math.isfinite(v) for v in numbers):
        raise CameraConfigError(f'{name} must be finite, got {list(numbers)}')
    return numbers


@dataclass(frozen=True)
class Lens:
    """A camera's intrinsics as sensor_msgs/CameraInfo carries them: K (row-major 3 x 3) and D
    (plumb_bob: k1, k2, t1, t2, k3). ``K[0] == 0`` means uncalibrated (no undistortion)."""

    camera_matrix: tuple[float, ...] = UNCALIBRATED_K
    distortion: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        matrix = _numbers('camera_matrix', self.camera_matrix)
        if len(matrix) != 9:
            raise CameraConfigError(f'camera_matrix must be 9 numbers (K, row-major), got '
                                    f'{len(matrix)}')
        distortion = _numbers('distortion', self.distortion)
        if len(distortion) not in (0, 4, 5, 8):
            raise CameraConfigError(f'distortion must be 0, 4, 5 or 8 numbers (plumb_bob or '
                                    f'rational_polynomial), got {len(distortion)}')
        if matrix[0] != 0.0 and (matrix[0] <= 0 or matrix[4] <= 0 or matrix[8] != 1.0):
            raise CameraConfigError(f'camera_matrix must have fx > 0, fy > 0 and K[8] = 1, got '
                                    f'{list(matrix)}')
        object.__setattr__(self, 'camera_matrix', matrix)
        object.__setattr__(self, 'distortion', distortion)

    @property
    def calibrated(self) -> bool:
        return self.camera_matrix[0] != 0.0

    @property
    def distorts(self) -> bool:
        return self.calibrated and any(self.distortion)

    def undistorted(self, pixels: np.ndarray) -> np.ndarray:
        """Pixel coordinates (N x 2) with the distortion taken out, in the same K."""
        if not self.distorts:
            return pixels
        import cv2

        matrix = np.array(self.camera_matrix).reshape(3, 3)
        # Iterated to 1e-12 px: the default five iterations leave 1e-3 px where k1 is large.
        result = cv2.undistortPoints(
            np.ascontiguousarray(pixels, np.float64).reshape(-1, 1, 2), matrix,
            np.array(self.distortion), None, None, matrix,
            (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12))
        return np.asarray(result).reshape(-1, 2)

    def distorted(self, pixels: np.ndarray) -> np.ndarray:
        """The inverse of :meth:`undistorted`: where an ideal pixel lands through the lens."""
        if not self.distorts:
            return pixels
        import cv2

        matrix = np.array(self.camera_matrix).reshape(3, 3)
        ideal = np.ascontiguousarray(pixels, np.float64).reshape(-1, 2)
        normalised = np.column_stack([(ideal[:, 0] - matrix[0, 2]) / matrix[0, 0],
                                      (ideal[:, 1] - matrix[1, 2]) / matrix[1, 1],
                                      np.ones(len(ideal))])
        projected, _ = cv2.projectPoints(normalised, np.zeros(3), np.zeros(3), matrix,
                                         np.array(self.distortion))
        return np.asarray(projected).reshape(-1, 2)

    def differs(self, other: Lens, relative: float = 1e-6) -> bool:
        """Whether ``other`` is another lens (K or D differ beyond ``relative``)."""
        def apart(a: tuple[float, ...], b: tuple[float, ...]) -> bool:
            padded = max(len(a), len(b))
            x = np.pad(np.array(a, float), (0, padded - len(a)))
            y = np.pad(np.array(b, float), (0, padded - len(b)))
            return bool(np.any(np.abs(x - y) > relative * np.maximum(1.0, np.abs(x))))
        return (apart(self.camera_matrix, other.camera_matrix)
                or apart(self.distortion, other.distortion))


@dataclass(frozen=True)
class PlaneMap:
    """One camera's map from its pixels to the platform plane (metres).

    Parameters
    ----------
    name : the camera (macro, micro).
    resolution_px : (width, height) the map holds for; other frames are refused.
    homography : row-major 3 x 3, from undistorted pixel (u, v, 1) to platform (x, y, 1).
    lens : the intrinsics the homography was fitted through.
    residual_px, residual_m : the calibration's RMS residual, in pixels and on the platform
        (0 for a nominal map).
    """

    name: str
    resolution_px: tuple[int, int]
    homography: tuple[float, ...]
    lens: Lens = Lens()
    residual_px: float = 0.0
    residual_m: float = 0.0

    def __post_init__(self) -> None:
        resolution = _numbers(f'{self.name}.resolution_px', self.resolution_px)
        if len(resolution) != 2 or any(v < 1 or v != int(v) for v in resolution):
            raise CameraConfigError(f'{self.name}.resolution_px must be two whole numbers of '
                                    f'pixels >= 1, got {list(self.resolution_px)}')
        check_resolution(f'{self.name}.resolution_px', (resolution[0], resolution[1]))
        object.__setattr__(self, 'resolution_px', (int(resolution[0]), int(resolution[1])))
        matrix = _numbers(f'{self.name}.homography', self.homography)
        if len(matrix) != 9:
            raise CameraConfigError(f'{self.name}.homography must be 9 numbers, got '
                                    f'{len(matrix)}')
        if abs(np.linalg.det(np.array(matrix).reshape(3, 3))) < 1e-300 or matrix[8] == 0.0:
            raise CameraConfigError(f'{self.name}.homography is singular: {list(matrix)}')
        object.__setattr__(self, 'homography', tuple(v / matrix[8] for v in matrix))
        for name in ('residual_px', 'residual_m'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise CameraConfigError(f'{self.name}.{name} must be a number >= 0, got '
                                        f'{value!r}')

    @classmethod
    def nominal(cls, camera: CameraModel, yaw_rad: float = 0.0, mirrored: bool = False,
                lens: Lens = Lens()) -> PlaneMap:
        """An ideal camera seeing ``camera``'s field on its resolution, turned by ``yaw_rad``
        about the field's centre (its image's x against the platform's x), its image flipped
        left to right if ``mirrored``; ``lens`` distorts around that ideal image."""
        columns, rows = (int(v) for v in camera.resolution_px)
        px, py = camera.pixel_size_m
        # Pixel centres to the camera's own frame, centred on the field's centre.
        to_camera = np.array([[px, 0.0, (0.5 - columns / 2) * px],
                              [0.0, -py, (rows / 2 - 0.5) * py],
                              [0.0, 0.0, 1.0]])
        flip = np.array([[-1.0, 0.0, columns - 1.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
        to_platform = np.array([[cos, -sin, camera.center_m[0]],
                                [sin, cos, camera.center_m[1]], [0.0, 0.0, 1.0]])
        matrix = to_platform @ to_camera @ (flip if mirrored else np.eye(3))
        return cls(camera.name, (columns, rows), tuple(matrix.ravel()), lens)

    @functools.cached_property
    def matrix(self) -> np.ndarray:
        return np.array(self.homography).reshape(3, 3)

    @functools.cached_property
    def inverse(self) -> np.ndarray:
        """From the platform to undistorted pixels."""
        return np.linalg.inv(self.matrix)

    def to_platform(self, pixels: np.ndarray) -> np.ndarray:
        """Platform points (N x 2, m) seen at ``pixels`` (N x 2, as the frame shows them)."""
        ideal = self.lens.undistorted(np.asarray(pixels, np.float64).reshape(-1, 2))
        return _apply(self.matrix, ideal)

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        """Where the frame shows platform ``points`` (N x 2, m): the inverse of
        :meth:`to_platform`."""
        ideal = _apply(self.inverse, np.asarray(points, np.float64).reshape(-1, 2))
        return self.lens.distorted(ideal)

    @functools.cached_property
    def centre_m(self) -> tuple[float, float]:
        """The platform point at the image's centre."""
        columns, rows = self.resolution_px
        x, y = self.to_platform(np.array([[(columns - 1) / 2, (rows - 1) / 2]]))[0]
        return float(x), float(y)

    @functools.cached_property
    def pixel_size_m(self) -> tuple[float, float]:
        """How far one pixel step along u and along v goes on the platform, at the centre."""
        columns, rows = self.resolution_px
        centre = np.array([(columns - 1) / 2, (rows - 1) / 2])
        points = self.to_platform(centre + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]))
        return (float(np.hypot(*(points[1] - points[0]))),
                float(np.hypot(*(points[2] - points[0]))))

    @functools.cached_property
    def pixels_per_metre(self) -> tuple[float, float]:
        """How many pixels along u and along v a platform disc of 1 m radius spans (at the
        centre, through the homography alone): a search window's half-size per metre."""
        inverse = self.inverse
        # The linear part at the image centre of the inverse homography.
        x, y = self.to_platform_undistorted(np.array([self.resolution_px]) / 2 - 0.5)[0]
        w = inverse[2, 0] * x + inverse[2, 1] * y + inverse[2, 2]
        u = inverse[0, 0] * x + inverse[0, 1] * y + inverse[0, 2]
        v = inverse[1, 0] * x + inverse[1, 1] * y + inverse[1, 2]
        jacobian = np.array([[inverse[0, 0] - u / w * inverse[2, 0],
                              inverse[0, 1] - u / w * inverse[2, 1]],
                             [inverse[1, 0] - v / w * inverse[2, 0],
                              inverse[1, 1] - v / w * inverse[2, 1]]]) / w
        return (float(np.hypot(*jacobian[0])), float(np.hypot(*jacobian[1])))

    def to_platform_undistorted(self, pixels: np.ndarray) -> np.ndarray:
        """Platform points seen at undistorted ``pixels`` (N x 2): the homography alone."""
        return _apply(self.matrix, np.asarray(pixels, np.float64).reshape(-1, 2))

    @property
    def mirrored(self) -> bool:
        """Whether the image is mirrored (the map keeps the plane's handedness)."""
        return bool(np.linalg.det(self.matrix[:2, :2]) > 0)

    @functools.cached_property
    def field_camera(self) -> CameraModel:
        """The camera as a field and a resolution (what picks the fiducial it tracks)."""
        return self.camera_model(0.0, 0.0)

    def camera_model(self, noise_px: float, quantisation_px: float) -> CameraModel:
        """The measurement model of this camera (its field and pixel at the centre), for the
        covariance a capture states."""
        px, py = self.pixel_size_m
        columns, rows = self.resolution_px
        return CameraModel(self.name, self.centre_m, (px * columns, py * rows), (columns, rows),
                           noise_px, quantisation_px)


def _apply(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    homogeneous = np.column_stack([points, np.ones(len(points))]) @ matrix.T
    result: np.ndarray = homogeneous[:, :2] / homogeneous[:, 2:3]
    return result
