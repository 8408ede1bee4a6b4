"""Images of the robot as an overhead camera would take them.

No rclpy: ``camera_node`` is a thin adapter of :func:`render`. The printed pattern is
:mod:`omni_micro_vision.fiducial`; what reads it back is :mod:`omni_micro_vision.tracking`.

**The scene.** The platform is a matte grey; the robot's top is the 9 mm dark chassis with a
printed fiducial: for the macro camera two white dots 4 mm apart on the robot's X axis (the
front one larger, so that the heading has a sign), and at the centre a smaller pair the micro
camera sees whole (0.6 mm apart). Both patterns are always there; each camera's tracker looks
for the pair whose size its pixels resolve. Several robots on one platform (a fleet)
are drawn in one frame, each with its code dots beside the pairs (:func:`render_robots`).

**The camera.** A sensor of ``resolution_px`` pixels over the camera's field (so 117 um and
1.56 um per pixel by default), a Gaussian point spread of ``psf_sigma_px``, photon shot noise
and read noise in electrons, quantisation to ``bit_depth`` bits, and motion blur: the exposure
integrates the robot's motion over ``exposure_s``. Noise comes from a generator seeded per
frame, so a frame is a function of (seed, frame number) and the robot's motion only. A camera
may be turned about its centre (``yaw_rad``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import CameraModel, camera_frame
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fiducial import (
    CHASSIS_LEVEL,
    CHASSIS_RADIUS_M,
    DOT_LEVEL,
    MACRO_FIDUCIAL,
    MICRO_FIDUCIAL,
    PLATFORM_LEVEL,
    Dot,
    code_dots,
)


@dataclass(frozen=True)
class Sensor:
    """The optics and sensor of a camera; ``resolution_px`` and the field set the pixel."""

    psf_sigma_px: float = 0.7
    full_well_e: float = 12000.0
    read_noise_e: float = 6.0
    bit_depth: int = 8
    exposure_s: float = 0.004

    def __post_init__(self) -> None:
        for name in ('psf_sigma_px', 'read_noise_e', 'exposure_s'):
            if not math.isfinite(getattr(self, name)) or getattr(self, name) < 0:
                raise CameraConfigError(f'{name} must be a finite number >= 0, got '
                                        f'{getattr(self, name)!r}')
        if not math.isfinite(self.full_well_e) or self.full_well_e <= 0:
            raise CameraConfigError(f'full_well_e must be > 0, got {self.full_well_e!r}')
        if self.bit_depth not in (8, 16):
            raise CameraConfigError(f'bit_depth must be 8 (mono8) or 16 (mono16), got '
                                    f'{self.bit_depth!r}')

    @property
    def encoding(self) -> str:
        return 'mono8' if self.bit_depth == 8 else 'mono16'

    @property
    def max_value(self) -> int:
        return (1 << self.bit_depth) - 1


def _pose_at(state: RobotState, t_s: float) -> tuple[float, float, float]:
    """Where the robot is ``t_s`` into the exposure, moving as at its start."""
    return (state.x_m + state.vx_m_s * t_s, state.y_m + state.vy_m_s * t_s,
            state.phi_rad + state.omega_rad_s * t_s)


def pixel_centres(camera: CameraModel) -> tuple[np.ndarray, np.ndarray]:
    """Platform x of each column's centre and y of each row's centre. Row 0 is the image's top,
    the platform's largest y: the camera looks down with its image x along the platform's x."""
    px, py = camera.pixel_size_m
    columns, rows = (int(v) for v in camera.resolution_px)
    left = camera.center_m[0] - camera.field_m[0] / 2
    top = camera.center_m[1] + camera.field_m[1] / 2
    return left + (np.arange(columns) + 0.5) * px, top - (np.arange(rows) + 0.5) * py


_PAIRS = tuple(dot for fiducial in (MACRO_FIDUCIAL, MICRO_FIDUCIAL)
               for dot in (fiducial.front, fiducial.back))


@dataclass(frozen=True)
class InView:
    """A robot in a frame: its state at the start of the exposure (platform frame) and the
    code it carries (``fiducial.code_dots``; None: a single robot's uncoded top)."""

    motion: RobotState
    code: int | None = None

    @property
    def dots(self) -> tuple[Dot, ...]:
        return _PAIRS + code_dots(self.code)


def _reflectance(xs: np.ndarray, ys: np.ndarray, poses: list[tuple[float, float, float]],
                 pixel_m: float, dots: tuple[Dot, ...] = _PAIRS) -> np.ndarray:
    """The scene's reflectance at the pixel centres ``xs`` x ``ys``, summed over the robot at
    each of ``poses`` (the instants of an exposure): the platform, the chassis's disc and the
    dots over it, each disc's edge a linear ramp one pixel wide (area-exact to first order)."""
    from omni_micro_vision.scene_kernel import reflectance_sum

    x_span, y_span = (float(xs[0]), float(xs[-1])), (float(ys[0]), float(ys[-1]))
    # Whether the chassis fills the window (the micro camera's whole 2 mm field) at an instant.
    fills = np.array([math.hypot(max(abs(x_span[0] - x), abs(x_span[1] - x)),
                                 max(abs(y_span[0] - y), abs(y_span[1] - y))) + pixel_m
                      < CHASSIS_RADIUS_M for x, y, _ in poses])
    turns = [(math.cos(phi), math.sin(phi)) for _, _, phi in poses]
    dots_x = np.array([[x + cos * dot.x_m - sin * dot.y_m for dot in dots]
                       for (x, _, _), (cos, sin) in zip(poses, turns, strict=True)])
    dots_y = np.array([[y + sin * dot.x_m + cos * dot.y_m for dot in dots]
                       for (_, y, _), (cos, sin) in zip(poses, turns, strict=True)])
    result: np.ndarray = reflectance_sum(
        np.ascontiguousarray(xs, np.float64), np.ascontiguousarray(ys, np.float64),
        np.array([pose[0] for pose in poses]), np.array([pose[1] for pose in poses]), fills,
        dots_x, dots_y, np.array([dot.radius_m for dot in dots]), pixel_m, CHASSIS_RADIUS_M,
        PLATFORM_LEVEL, CHASSIS_LEVEL, DOT_LEVEL)
    return result


# The frame is put together in square blocks: a block the robot's edge, a dot or their blur
# cannot reach is a flat field (platform or chassis), copied from a pre-drawn noisy field;
# only the others are computed from the scene.
BLOCK_PX = 64
# Pre-drawn flat fields are seeded by this and the level alone, and each frame takes a window
# at a seeded offset into one twice its size: a frame stays a function of its own seed.
_FLAT_FIELD_SEED = 20081016


def _counts(electrons: np.ndarray, sensor: Sensor, normal: np.ndarray) -> np.ndarray:
    """Shot noise (Poisson, as a Gaussian at these counts) and read noise, then quantisation."""
    sigma = np.sqrt(electrons + np.float32(sensor.read_noise_e ** 2))
    noisy = electrons + sigma * normal
    counts = np.rint(noisy * np.float32(sensor.max_value / sensor.full_well_e))
    dtype = np.uint8 if sensor.bit_depth == 8 else np.uint16
    result: np.ndarray = np.clip(counts, 0, sensor.max_value).astype(dtype)
    return result


@functools.lru_cache(maxsize=8)
def _flat_field(sensor: Sensor, level: float, pixels: int) -> np.ndarray:
    """Noisy counts of a flat ``level``, ``2 * pixels`` long (a frame is a window into it)."""
    rng = np.random.default_rng([_FLAT_FIELD_SEED, round(level * 1e6), pixels])
    electrons = np.full(2 * pixels, level * sensor.full_well_e, dtype=np.float32)
    return _counts(electrons, sensor, rng.standard_normal(2 * pixels, dtype=np.float32))


def _distance_range(x0: np.ndarray, x1: np.ndarray, y0: np.ndarray, y1: np.ndarray,
                    cx: float, cy: float) -> tuple[np.ndarray, np.ndarray]:
    """Least and greatest distance from (cx, cy) to the rectangles [x0, x1] x [y0, y1]."""
    near_x = np.maximum(np.maximum(x0 - cx, cx - x1), 0.0)
    near_y = np.maximum(np.maximum(y0 - cy, cy - y1), 0.0)
    far_x = np.maximum(np.abs(x0 - cx), np.abs(x1 - cx))
    far_y = np.maximum(np.abs(y0 - cy), np.abs(y1 - cy))
    return np.hypot(near_x, near_y), np.hypot(far_x, far_y)


def _exposed(camera: CameraModel, xs: np.ndarray, ys: np.ndarray, robots: Sequence[InView],
             exposure_s: float, steps: int) -> np.ndarray:
    """The scene at ``xs`` x ``ys`` averaged over the exposure (float32), at ``steps`` instants:
    each robot's over the platform, added (their discs never overlap, so each pixel is one
    robot's or the platform's).
    """
    first, *others = (_exposed_one(camera, xs, ys, robot, exposure_s, steps)
                      for robot in robots)
    for other in others:
        first = first + (other - np.float32(PLATFORM_LEVEL))
    return first


def _exposed_one(camera: CameraModel, xs: np.ndarray, ys: np.ndarray, robot: InView,
                 exposure_s: float, steps: int) -> np.ndarray:
    """One robot's scene at ``xs`` x ``ys`` over the platform, averaged over the exposure.

    A robot that turns by less than a quarter pixel is only translated: the scene is then
    computed once, at mid-exposure, on a window wider by the travel, and smeared along it by
    one convolution (what the instants' shifted copies add up to, bilinear between pixels)
    instead of once per instant.
    """
    import cv2

    motion, dots = robot.motion, robot.dots
    px, py = camera.pixel_size_m
    pixel_m = math.sqrt(px * py)
    instants = [exposure_s * (step + 0.5) / steps for step in range(steps)]
    turn_px = abs(motion.omega_rad_s) * exposure_s * CHASSIS_RADIUS_M / pixel_m
    if steps == 1 or turn_px >= 0.25:
        patch = _reflectance(xs, ys, [_pose_at(motion, t) for t in instants], pixel_m,
                             dots)
        return (patch / steps).astype(np.float32)
    middle = 0.5 * exposure_s
    # Each instant's shift from mid-exposure in pixels (rows grow downwards, against y).
    shifts = [((t - middle) * motion.vx_m_s / px, -(t - middle) * motion.vy_m_s / py)
              for t in instants]
    margin = math.ceil(max(max(abs(u), abs(v)) for u, v in shifts)) + 1
    wide_xs = np.concatenate([xs[0] - px * np.arange(margin, 0, -1), xs,
                              xs[-1] + px * np.arange(1, margin + 1)])
    wide_ys = np.concatenate([ys[0] + py * np.arange(margin, 0, -1), ys,
                              ys[-1] - py * np.arange(1, margin + 1)])
    scene = _reflectance(wide_xs, wide_ys, [_pose_at(motion, middle)], pixel_m, dots).astype(
        np.float32)
    # filter2D correlates: the value at a pixel is the scene an instant's shift behind it.
    kernel = np.zeros((2 * margin + 1, 2 * margin + 1), np.float32)
    for u, v in shifts:
        column, row = margin - u, margin - v
        c, r = math.floor(column), math.floor(row)
        fc, fr = column - c, row - r
        kernel[r, c] += (1 - fr) * (1 - fc) / steps
        kernel[r, c + 1] += (1 - fr) * fc / steps
        kernel[r + 1, c] += fr * (1 - fc) / steps
        kernel[r + 1, c + 1] += fr * fc / steps
    smeared = cv2.filter2D(scene, -1, kernel, borderType=cv2.BORDER_REPLICATE)
    return np.asarray(smeared[margin:-margin, margin:-margin], np.float32)


def render(camera: CameraModel, sensor: Sensor, motion: RobotState,
           rng: np.random.Generator, yaw_rad: float = 0.0) -> np.ndarray:
    """One frame (rows x columns, uint8 or uint16) of ``camera`` seeing the robot, whose state
    (pose and velocity, platform frame) at the start of the exposure is ``motion``; the camera
    turned by ``yaw_rad`` about its centre (a real mount is never square to the platform).

    Blocks of the frame that only the flat platform or the flat chassis reach (with the blur
    and the motion over the exposure) are windows of pre-drawn noisy flat fields at an offset
    drawn from ``rng``; the others are computed from the scene, blurred and given fresh noise
    from ``rng``.
    """
    return render_robots(camera, sensor, [InView(motion)], rng, yaw_rad)


@dataclass(frozen=True)
class _Reach:
    """Where one robot can touch a frame: its mid-exposure pose and how far past an outline
    (the edge ramp, the blur, half its motion) a pixel is still touched."""

    pose: tuple[float, float, float]
    reach_m: float
    turn_rad: float
    dots: tuple[Dot, ...]


def render_robots(camera: CameraModel, sensor: Sensor, robots: Sequence[InView],
                  rng: np.random.Generator, yaw_rad: float = 0.0) -> np.ndarray:
    """One frame of ``camera`` seeing ``robots`` (a fleet's, each with its code), as
    :func:`render` sees one: the same frame for one uncoded robot."""
    import cv2

    if not robots:
        raise CameraConfigError('a frame needs at least one robot to draw')
    if yaw_rad:
        cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
        robots = [InView(RobotState(*camera_frame(camera, yaw_rad, robot.motion.x_m,
                                                  robot.motion.y_m, robot.motion.phi_rad),
                                    cos * robot.motion.vx_m_s + sin * robot.motion.vy_m_s,
                                    -sin * robot.motion.vx_m_s + cos * robot.motion.vy_m_s,
                                    robot.motion.omega_rad_s), robot.code) for robot in robots]
    xs, ys = pixel_centres(camera)
    columns, rows = xs.size, ys.size
    px, py = camera.pixel_size_m
    pixel_m = math.sqrt(px * py)
    halo_px = math.ceil(4 * sensor.psf_sigma_px) + 1
    reaches, steps = [], 1
    for robot in robots:
        start, end = _pose_at(robot.motion, 0.0), _pose_at(robot.motion, sensor.exposure_s)
        shift_m = 0.5 * math.hypot(end[0] - start[0], end[1] - start[1])
        turn_rad = 0.5 * abs(end[2] - start[2])
        travel_px = 2 * max(shift_m, turn_rad * CHASSIS_RADIUS_M) / pixel_m
        steps = max(steps, int(min(32, max(1, math.ceil(travel_px / 0.5)))))
        reaches.append(_Reach(_pose_at(robot.motion, 0.5 * sensor.exposure_s),
                              (halo_px + 1) * pixel_m + shift_m, turn_rad, robot.dots))

    offset = int(rng.integers(0, rows * columns))
    window = slice(offset, offset + rows * columns)
    frame = _flat_field(sensor, PLATFORM_LEVEL, rows * columns)[window].reshape(rows, columns)
    frame = frame.copy()
    flat_fields: dict[float, np.ndarray] = {}
    # Only the blocks a chassis (and its reach) may cover are looked at.
    top_m = camera.center_m[1] + camera.field_m[1] / 2
    left_m = camera.center_m[0] - camera.field_m[0] / 2
    extents = [(reach.pose[0], reach.pose[1], CHASSIS_RADIUS_M + reach.reach_m)
               for reach in reaches]
    first_row = max(0, min(int((top_m - (y + extent)) / py) for x, y, extent in extents))
    last_row = min(rows, max(int((top_m - (y - extent)) / py) + 1 for x, y, extent in extents))
    first_column = max(0, min(int((x - extent - left_m) / px) for x, y, extent in extents))
    last_column = min(columns, max(int((x + extent - left_m) / px) + 1
                                   for x, y, extent in extents))
    tops = np.arange(first_row // BLOCK_PX * BLOCK_PX, last_row, BLOCK_PX)
    lefts = np.arange(first_column // BLOCK_PX * BLOCK_PX, last_column, BLOCK_PX)
    bottoms, rights = np.minimum(tops + BLOCK_PX, rows), np.minimum(lefts + BLOCK_PX, columns)
    # Each block's span in metres, rows x columns of blocks.
    y_low, y_high = ys[bottoms - 1][:, None], ys[tops][:, None]
    x_low, x_high = xs[lefts][None, :], xs[rights - 1][None, :]
    # Per robot, the blocks within its reach (else the platform only, as far as it goes), and
    # of those the ones an outline (its chassis's or a dot's) reaches: computed. A block within
    # a robot's reach that no outline touches is wholly inside its chassis, or inside a dot
    # (the macro dots fill micro blocks).
    within = np.zeros((tops.size, lefts.size, len(reaches)), dtype=bool)
    touched = np.zeros((tops.size, lefts.size), dtype=bool)
    in_dot = np.zeros_like(touched)
    for index, reach in enumerate(reaches):
        x, y, phi = reach.pose
        near, far = _distance_range(x_low, x_high, y_low, y_high, x, y)
        within[:, :, index] = near <= CHASSIS_RADIUS_M + reach.reach_m
        outline = far > CHASSIS_RADIUS_M - reach.reach_m
        for dot in reach.dots:
            dot_reach = reach.reach_m + reach.turn_rad * math.hypot(dot.x_m, dot.y_m)
            near, far = _distance_range(
                x_low, x_high, y_low, y_high,
                x + math.cos(phi) * dot.x_m - math.sin(phi) * dot.y_m,
                y + math.sin(phi) * dot.x_m + math.cos(phi) * dot.y_m)
            outline |= (near < dot.radius_m + dot_reach) & (far > dot.radius_m - dot_reach)
            in_dot |= within[:, :, index] & (far <= dot.radius_m - dot_reach)
        touched |= within[:, :, index] & outline
    for (i, j) in zip(*np.nonzero(within.any(axis=2)), strict=True):
        top, bottom, left, right = int(tops[i]), int(bottoms[i]), int(lefts[j]), int(rights[j])
        if not touched[i, j]:
            level = DOT_LEVEL if in_dot[i, j] else CHASSIS_LEVEL
            if level not in flat_fields:
                flat_fields[level] = _flat_field(sensor, level, rows * columns)[
                    window].reshape(rows, columns)
            frame[top:bottom, left:right] = flat_fields[level][top:bottom, left:right]
            continue
        # The block and a halo around it, so that the blur at its border is the scene's.
        r0, r1 = max(0, top - halo_px), min(rows, bottom + halo_px)
        c0, c1 = max(0, left - halo_px), min(columns, right + halo_px)
        near_robots = [robot for index, robot in enumerate(robots) if within[i, j, index]]
        signal = _exposed(camera, xs[c0:c1], ys[r0:r1], near_robots, sensor.exposure_s, steps)
        if sensor.psf_sigma_px > 0:
            signal = np.asarray(cv2.GaussianBlur(signal, (0, 0), sensor.psf_sigma_px,
                                                 borderType=cv2.BORDER_REPLICATE), np.float32)
        inner = signal[top - r0:top - r0 + bottom - top, left - c0:left - c0 + right - left]
        frame[top:bottom, left:right] = _counts(
            inner * np.float32(sensor.full_well_e), sensor,
            rng.standard_normal(inner.shape, dtype=np.float32))
    return frame


def warm_up(camera: CameraModel, sensor: Sensor, yaw_rad: float = 0.0) -> None:
    """Draw one throwaway frame of a moving, turning robot in the middle of ``camera``'s field:
    the scene kernel loads from numba's cache and the flat fields are drawn (together some
    0.3 s, which the first frame would otherwise pay inside the loop's time). Frames drawn
    after it are the same as without it: each is a function of its own seed."""
    x, y = camera.center_m
    render(camera, sensor, RobotState(x, y, 0.3, 0.01, 0.002, 0.05), np.random.default_rng(0),
           yaw_rad)


def expose(reflectance: np.ndarray, sensor: Sensor, rng: np.random.Generator) -> np.ndarray:
    """A whole frame of a still scene of ``reflectance`` (rows x columns, fractions of the full
    well): the point spread, shot and read noise, quantisation, as :func:`render` gives the
    robot (a calibration target, say)."""
    import cv2

    signal = np.asarray(reflectance, np.float32)
    if sensor.psf_sigma_px > 0:
        signal = np.asarray(cv2.GaussianBlur(signal, (0, 0), sensor.psf_sigma_px,
                                             borderType=cv2.BORDER_REPLICATE), np.float32)
    return _counts(signal * np.float32(sensor.full_well_e), sensor,
                   rng.standard_normal(signal.shape, dtype=np.float32))
