"""A camera's map to the platform, fitted from its frames of a target lying on it.

As image_pipeline divides the work: the driver's CameraInfo carries the lens (K, D, from
camera_calibration), and this fits what is left, one homography from the undistorted image to
the platform plane. OpenCV finds the target's points on the mean of the frames (a chessboard's
inner corners with ``findChessboardCorners`` refined by ``cornerSubPix``; an asymmetric circle
grid's centres with ``findCirclesGrid``) and fits the homography (``findHomography`` on
``undistortPoints``). Without a lens in the CameraInfo (K all zero) the homography is fitted to
the frame's own pixels, and a lens that distorts shows as a poor fit.

Which point is which: OpenCV returns them along the pattern's rows from one end or the other.
A mirrored image is told apart only by the user (a target cannot show it), so the fit keeps the
orderings whose handedness agrees with ``mirrored``; of those two, half a turn apart, a
chessboard's is the one whose corner square at its lowest x and y is black, a circle grid's the
one that fits (its rows are staggered: the other cannot be a homography of it). No rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import Lens, PlaneMap
from omni_micro_vision.targets import Target

# A fit whose corners miss by more than this (RMS, pixels) is refused: a target that is not
# flat or not where it was said to be, or a lens the CameraInfo does not state.
MAX_RESIDUAL_PX = 0.5


class CalibrationError(CameraConfigError):
    """The frames cannot calibrate the camera; the message says why."""


@dataclass(frozen=True)
class Calibration:
    """A fitted map and how well it fits."""

    plane: PlaneMap
    corners: int
    frames: int

    def params_yaml(self, mirrored: bool) -> str:
        """A params file for tracker_node holding this camera's calibration."""
        plane = self.plane
        name = plane.name

        def numbers(values: tuple[float, ...]) -> str:
            return '[' + ', '.join(repr(float(v)) for v in values) + ']'

        return (f'# {name} camera calibration by omni-micro calibrate-camera: give it to '
                f'tracker_node beside\n# your own params file (--params-file yours.yaml '
                f'--params-file this.yaml). RMS residual\n# {plane.residual_px:.4g} px, '
                f'{plane.residual_m * 1e6:.4g} um on the platform, over {self.corners} corners '
                f'of {self.frames} frames.\n'
                f'tracker_node:\n  ros__parameters:\n    {name}:\n'
                f'      mirrored: {"true" if mirrored else "false"}\n'
                f'      calibration:\n'
                f'        resolution_px: [{plane.resolution_px[0]}, {plane.resolution_px[1]}]\n'
                f'        camera_matrix: {numbers(plane.lens.camera_matrix)}\n'
                f'        distortion: {numbers(plane.lens.distortion or (0.0,) * 5)}\n'
                f'        homography: {numbers(plane.homography)}\n'
                f'        residual_px: {plane.residual_px!r}\n'
                f'        residual_m: {plane.residual_m!r}\n')


def calibrate(name: str, frames: list[np.ndarray], lens: Lens, target: Target,
              mirrored: bool) -> Calibration:
    """Camera ``name``'s map from ``frames`` (grey, all of one size) of ``target``.

    Raises
    ------
    CalibrationError
        No frames, a target that looks the same turned half a turn, a target not found or
        found ambiguously, or a poor fit; the message says which and what to do.
    """

    if not frames:
        raise CalibrationError('no frames to calibrate from')
    columns, rows = target.pattern
    if target.half_turn_symmetric:
        raise CalibrationError(
            f'a chessboard of {columns}x{rows} inner corners looks the same turned half a '
            'turn, so no image can say which way it lies: use one with an odd and an even '
            'count (9x6, say)' if target.kind == 'chessboard' else
            f'a circle grid of {columns}x{rows} with an even number of rows looks the same '
            'turned half a turn, so no image can say which way it lies: use an odd number '
            'of rows (4x11, say)')
    height, width = frames[0].shape
    full_scale = float(np.iinfo(frames[0].dtype).max) if frames[0].dtype.kind == 'u' else 1.0
    # The mean of the frames: the target is still, the noise averages out.
    mean = np.mean(np.stack(frames).astype(np.float32), axis=0) / np.float32(full_scale)
    image8 = np.clip(mean * 255.0 / max(float(mean.max()), 1e-6), 0, 255).astype(np.uint8)
    grid = _detect(target, image8, mean, len(frames))
    truth = target.points_m()
    fits = []
    for row_step in (1, -1):
        for column_step in (1, -1):
            corners = grid[::row_step, ::column_step]
            plane = _fit(name, (width, height), corners, truth, lens)
            if plane.mirrored != mirrored:
                continue
            if (_corner_square_is_black(mean, corners) if target.kind == 'chessboard'
                    else plane.residual_px <= MAX_RESIDUAL_PX):
                fits.append((plane, corners))
    if len(fits) != 1:
        raise CalibrationError(
            f'the target is ambiguous: {len(fits)} ways to read it agree with a '
            f'{"mirrored" if mirrored else "plain"} image and a black square at its lowest x '
            f'and y (is --mirrored right?)')
    plane, corners = fits[0]
    if plane.residual_px > MAX_RESIDUAL_PX:
        raise CalibrationError(
            f'a poor fit: the points miss by {plane.residual_px:.3g} px RMS (at most '
            f'{MAX_RESIDUAL_PX} px): check --pitch-mm and that the target lies flat, or give '
            "the camera's lens (K, D) in its CameraInfo")
    return Calibration(plane, corners.size // 2, len(frames))


def _detect(target: Target, image8: np.ndarray, mean: np.ndarray, frames: int) -> np.ndarray:
    """The target's points as OpenCV finds them, rows x columns x 2 pixels."""
    import cv2

    columns, rows = target.pattern
    if target.kind == 'chessboard':
        found, detected = cv2.findChessboardCorners(
            image8, (columns, rows),
            flags=cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE)
        what = f'chessboard of {columns}x{rows} inner corners'
    else:
        found, detected = cv2.findCirclesGrid(image8, (columns, rows),
                                              flags=cv2.CALIB_CB_ASYMMETRIC_GRID)
        what = f'asymmetric circle grid of {columns}x{rows}'
    if not found:
        raise CalibrationError(f'no {what} found in the {frames} frames: check --pattern '
                               '(COLSxROWS, as OpenCV counts them) and that the whole target '
                               'and its white border are in the image')
    points: np.ndarray = np.asarray(detected, np.float32)
    if target.kind == 'chessboard':
        points = cv2.cornerSubPix(mean, points, (5, 5), (-1, -1),
                                  (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4))
    return np.asarray(points, np.float64).reshape(rows, columns, 2)


def _fit(name: str, resolution: tuple[int, int], corners: np.ndarray, truth: np.ndarray,
         lens: Lens) -> PlaneMap:
    """The homography from ``corners`` (as the frame shows them) to ``truth`` on the platform,
    and its residuals."""
    import cv2

    seen = corners.reshape(-1, 2)
    platform = truth.reshape(-1, 2)
    # In millimetres: the fit's numbers stay near one.
    fitted, _ = cv2.findHomography(lens.undistorted(seen), platform * 1e3, 0)
    if fitted is None:
        raise CalibrationError('the corners found give no homography (are they in a line?)')
    to_metres = np.diag([1e-3, 1e-3, 1.0])
    plane = PlaneMap(name, resolution, tuple((to_metres @ fitted).ravel()), lens)
    residual_px = math.sqrt(float(np.mean(np.sum((plane.to_pixels(platform) - seen) ** 2,
                                                 axis=1))))
    residual_m = math.sqrt(float(np.mean(np.sum((plane.to_platform(seen) - platform) ** 2,
                                                axis=1))))
    return PlaneMap(name, resolution, plane.homography, lens, residual_px, residual_m)


def _corner_square_is_black(image: np.ndarray, corners: np.ndarray) -> bool:
    """Whether the square beyond corner [0, 0] (the board's lowest x and y) is darker than its
    neighbour along the board's x, in ``image``."""
    first, along, across = corners[0, 0], corners[0, 1] - corners[0, 0], corners[1, 0] - \
        corners[0, 0]

    def level(point: np.ndarray) -> float:
        u, v = (round(float(c)) for c in point)
        reach = max(1, int(0.15 * min(np.hypot(*along), np.hypot(*across))))
        patch = image[max(0, v - reach):v + reach + 1, max(0, u - reach):u + reach + 1]
        return float(patch.mean()) if patch.size else math.nan

    corner_square = level(first - 0.5 * along - 0.5 * across)
    neighbour = level(first + 0.5 * along - 0.5 * across)
    return corner_square < neighbour
