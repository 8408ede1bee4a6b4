"""Images of the robot as an overhead camera would take them, and the tracker that reads them.

No rclpy: ``camera_node`` and ``tracker_node`` are thin adapters of these.

**The scene.** The platform is a matte grey; the robot's top is the 9 mm dark chassis with a
printed fiducial: for the macro camera two white dots 4 mm apart on the robot's X axis (the
front one larger, so that the heading has a sign), and at the centre a smaller pair the micro
camera sees whole (0.6 mm apart). Both patterns are always there; each camera's tracker looks
for the pair whose size its pixels resolve.

**The camera.** A sensor of ``resolution_px`` pixels over the camera's field (so 117 um and
1.56 um per pixel by default), a Gaussian point spread of ``psf_sigma_px``, photon shot noise
and read noise in electrons, quantisation to ``bit_depth`` bits, and motion blur: the exposure
integrates the robot's motion over ``exposure_s``. Noise comes from a generator seeded per
frame, so a frame is a function of (seed, frame number) and the robot's motion only. A camera
may be turned about its centre (``yaw_rad``).

**The tracker.** Threshold halfway between the surround and the brightest dots, outer
contours, the two dots picked by their expected areas, each located by its intensity-weighted
centroid (sub-pixel), and the pose from their midpoint and direction; first near the last pose
when it is known. A frame where the pair is not found, is cut by the image's edge or is
ambiguous gives no pose and says why.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG, CameraConfigError, CameraModel


@dataclass(frozen=True)
class Dot:
    """A printed dot on the robot's top: centre in the robot frame (m) and radius (m)."""

    x_m: float
    y_m: float
    radius_m: float


@dataclass(frozen=True)
class Fiducial:
    """A pair of dots on the robot's X axis: ``front`` larger than ``back``."""

    front: Dot
    back: Dot

    @property
    def baseline_m(self) -> float:
        return math.hypot(self.front.x_m - self.back.x_m, self.front.y_m - self.back.y_m)


MACRO_FIDUCIAL = Fiducial(Dot(2.0e-3, 0.0, 0.9e-3), Dot(-2.0e-3, 0.0, 0.5e-3))
MICRO_FIDUCIAL = Fiducial(Dot(0.3e-3, 0.0, 0.06e-3), Dot(-0.3e-3, 0.0, 0.035e-3))
CHASSIS_RADIUS_M = 4.5e-3
# Reflectances: what fraction of the full well a pixel collects in one exposure.
PLATFORM_LEVEL = 0.35
CHASSIS_LEVEL = 0.12
DOT_LEVEL = 0.9


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


def _coverage(distance_m: np.ndarray, radius_m: float, pixel_m: float) -> np.ndarray:
    """How much of a pixel a disc covers, from the distance of the pixel's centre to the disc's
    centre: a linear ramp one pixel wide across the edge (area-exact to first order)."""
    return np.clip(0.5 - (distance_m - radius_m) / pixel_m, 0.0, 1.0)


def _reflectance(xs: np.ndarray, ys: np.ndarray, pose: tuple[float, float, float],
                 pixel_m: float) -> np.ndarray:
    """The scene's reflectance at the pixel centres ``xs`` x ``ys`` for the robot at ``pose``;
    each dot only where it can reach (a dot is a few pixels in a frame of a million)."""
    x, y, phi = pose
    farthest = math.hypot(max(abs(xs[0] - x), abs(xs[-1] - x)),
                          max(abs(ys[0] - y), abs(ys[-1] - y)))
    if farthest + pixel_m < CHASSIS_RADIUS_M:
        # The chassis fills the window (the micro camera's whole 2 mm field).
        image = np.full((ys.size, xs.size), CHASSIS_LEVEL)
    else:
        image = PLATFORM_LEVEL + (CHASSIS_LEVEL - PLATFORM_LEVEL) * _coverage(
            np.hypot(xs[None, :] - x, ys[:, None] - y), CHASSIS_RADIUS_M, pixel_m)
    cos, sin = math.cos(phi), math.sin(phi)
    for fiducial in (MACRO_FIDUCIAL, MICRO_FIDUCIAL):
        for dot in (fiducial.front, fiducial.back):
            cx = x + cos * dot.x_m - sin * dot.y_m
            cy = y + sin * dot.x_m + cos * dot.y_m
            reach = dot.radius_m + pixel_m
            columns = np.nonzero(np.abs(xs - cx) <= reach)[0]
            rows = np.nonzero(np.abs(ys - cy) <= reach)[0]
            if not columns.size or not rows.size:
                continue
            window = (slice(rows[0], rows[-1] + 1), slice(columns[0], columns[-1] + 1))
            covered = _coverage(np.hypot(xs[window[1]][None, :] - cx,
                                         ys[window[0]][:, None] - cy), dot.radius_m, pixel_m)
            image[window] += (DOT_LEVEL - image[window]) * covered
    return image


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


def _exposed(camera: CameraModel, xs: np.ndarray, ys: np.ndarray, motion: RobotState,
             exposure_s: float, steps: int) -> np.ndarray:
    """The scene at ``xs`` x ``ys`` averaged over the exposure (float32), at ``steps`` instants.

    A robot that turns by less than a quarter pixel is only translated: the scene is then
    computed once, at mid-exposure, on a window wider by the travel, and smeared along it by
    one convolution (what the instants' shifted copies add up to, bilinear between pixels)
    instead of once per instant.
    """
    import cv2

    px, py = camera.pixel_size_m
    pixel_m = math.sqrt(px * py)
    instants = [exposure_s * (step + 0.5) / steps for step in range(steps)]
    turn_px = abs(motion.omega_rad_s) * exposure_s * CHASSIS_RADIUS_M / pixel_m
    if steps == 1 or turn_px >= 0.25:
        patch = sum(_reflectance(xs, ys, _pose_at(motion, t), pixel_m) for t in instants)
        return (np.asarray(patch) / steps).astype(np.float32)
    middle = 0.5 * exposure_s
    # Each instant's shift from mid-exposure in pixels (rows grow downwards, against y).
    shifts = [((t - middle) * motion.vx_m_s / px, -(t - middle) * motion.vy_m_s / py)
              for t in instants]
    margin = math.ceil(max(max(abs(u), abs(v)) for u, v in shifts)) + 1
    wide_xs = np.concatenate([xs[0] - px * np.arange(margin, 0, -1), xs,
                              xs[-1] + px * np.arange(1, margin + 1)])
    wide_ys = np.concatenate([ys[0] + py * np.arange(margin, 0, -1), ys,
                              ys[-1] - py * np.arange(1, margin + 1)])
    scene = _reflectance(wide_xs, wide_ys, _pose_at(motion, middle), pixel_m).astype(np.float32)
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


def checked_cameras(names: list[str]) -> list[str]:
    """The cameras a node is to use (its ``cameras`` parameter): at least one, each of the
    rig's, else a CameraConfigError naming the value."""
    known = sorted(vars(DEFAULT_RIG))
    unknown = sorted(set(names) - set(known))
    if not names:
        raise CameraConfigError(f'cameras must name at least one of {known}')
    if unknown:
        raise CameraConfigError(f'cameras: {unknown[0]!r} is not one of {known}')
    return list(names)


def checked_yaw(name: str, value: object) -> float:
    """A camera's turn about its centre: finite radians within +-pi/4, else a
    CameraConfigError naming ``name``."""
    try:
        angle = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise CameraConfigError(f'{name} must be a number of radians, got {value!r}') from None
    if not math.isfinite(angle) or abs(angle) > math.pi / 4:
        raise CameraConfigError(f"{name} must be finite and within +-pi/4 rad (the image's x "
                                f"roughly along the platform's), got {value!r}")
    return angle


def camera_frame(camera: CameraModel, yaw_rad: float, x_m: float, y_m: float,
                 phi_rad: float) -> tuple[float, float, float]:
    """A platform pose as seen in the frame of a camera turned by ``yaw_rad`` about its
    centre (its image's x axis is the platform's x turned by yaw)."""
    cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
    dx, dy = x_m - camera.center_m[0], y_m - camera.center_m[1]
    return (camera.center_m[0] + cos * dx + sin * dy, camera.center_m[1] - sin * dx + cos * dy,
            phi_rad - yaw_rad)


def platform_frame(camera: CameraModel, yaw_rad: float, x_m: float, y_m: float,
                   phi_rad: float) -> tuple[float, float, float]:
    """The inverse of :func:`camera_frame`."""
    return camera_frame(camera, -yaw_rad, x_m, y_m, phi_rad)


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
    import cv2

    if yaw_rad:
        cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
        motion = RobotState(*camera_frame(camera, yaw_rad, motion.x_m, motion.y_m,
                                          motion.phi_rad),
                            cos * motion.vx_m_s + sin * motion.vy_m_s,
                            -sin * motion.vx_m_s + cos * motion.vy_m_s, motion.omega_rad_s)
    xs, ys = pixel_centres(camera)
    columns, rows = xs.size, ys.size
    px, py = camera.pixel_size_m
    pixel_m = math.sqrt(px * py)
    start, end = _pose_at(motion, 0.0), _pose_at(motion, sensor.exposure_s)
    middle = _pose_at(motion, 0.5 * sensor.exposure_s)
    shift_m = 0.5 * math.hypot(end[0] - start[0], end[1] - start[1])
    turn_rad = 0.5 * abs(end[2] - start[2])
    travel_px = 2 * max(shift_m, turn_rad * CHASSIS_RADIUS_M) / pixel_m
    steps = int(min(32, max(1, math.ceil(travel_px / 0.5))))
    halo_px = math.ceil(4 * sensor.psf_sigma_px) + 1
    # How far from the mid-exposure outline a pixel can still be touched: the edge ramp, the
    # blur and half the motion.
    reach_m = (halo_px + 1) * pixel_m + shift_m

    offset = int(rng.integers(0, rows * columns))
    window = slice(offset, offset + rows * columns)
    frame = _flat_field(sensor, PLATFORM_LEVEL, rows * columns)[window].reshape(rows, columns)
    frame = frame.copy()
    flat_fields: dict[float, np.ndarray] = {}
    x, y, phi = middle
    dots = [(x + math.cos(phi) * dot.x_m - math.sin(phi) * dot.y_m,
             y + math.sin(phi) * dot.x_m + math.cos(phi) * dot.y_m,
             dot.radius_m, reach_m + turn_rad * math.hypot(dot.x_m, dot.y_m))
            for fiducial in (MACRO_FIDUCIAL, MICRO_FIDUCIAL) for dot in (fiducial.front,
                                                                           fiducial.back)]
    # Only the blocks the chassis (and its reach) may cover are looked at.
    extent = CHASSIS_RADIUS_M + reach_m
    first_row = max(0, int((camera.center_m[1] + camera.field_m[1] / 2 - (y + extent)) / py))
    last_row = min(rows, int((camera.center_m[1] + camera.field_m[1] / 2 - (y - extent)) / py)
                   + 1)
    first_column = max(0, int((x - extent - (camera.center_m[0] - camera.field_m[0] / 2)) / px))
    last_column = min(columns, int((x + extent - (camera.center_m[0] - camera.field_m[0] / 2))
                                   / px) + 1)
    tops = np.arange(first_row // BLOCK_PX * BLOCK_PX, last_row, BLOCK_PX)
    lefts = np.arange(first_column // BLOCK_PX * BLOCK_PX, last_column, BLOCK_PX)
    bottoms, rights = np.minimum(tops + BLOCK_PX, rows), np.minimum(lefts + BLOCK_PX, columns)
    # Each block's span in metres, rows x columns of blocks.
    y_low, y_high = ys[bottoms - 1][:, None], ys[tops][:, None]
    x_low, x_high = xs[lefts][None, :], xs[rights - 1][None, :]
    near, far = _distance_range(x_low, x_high, y_low, y_high, x, y)
    inside = near <= CHASSIS_RADIUS_M + reach_m        # else the platform only
    # An outline (the chassis's or a dot's) within reach: computed; else the block is wholly
    # inside the chassis, or inside a dot (the macro dots fill micro blocks).
    touched = far > CHASSIS_RADIUS_M - reach_m
    in_dot = np.zeros_like(touched)
    for cx, cy, radius, reach in dots:
        near, far = _distance_range(x_low, x_high, y_low, y_high, cx, cy)
        touched |= (near < radius + reach) & (far > radius - reach)
        in_dot |= far <= radius - reach
    for (i, j) in zip(*np.nonzero(inside), strict=True):
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
        signal = _exposed(camera, xs[c0:c1], ys[r0:r1], motion, sensor.exposure_s, steps)
        if sensor.psf_sigma_px > 0:
            signal = np.asarray(cv2.GaussianBlur(signal, (0, 0), sensor.psf_sigma_px,
                                                 borderType=cv2.BORDER_REPLICATE), np.float32)
        inner = signal[top - r0:top - r0 + bottom - top, left - c0:left - c0 + right - left]
        frame[top:bottom, left:right] = _counts(
            inner * np.float32(sensor.full_well_e), sensor,
            rng.standard_normal(inner.shape, dtype=np.float32))
    return frame


@dataclass(frozen=True)
class Track:
    """The tracker's answer for one frame: a pose (x, y, heading in the platform frame), or
    why there is none."""

    pose: tuple[float, float, float] | None = None
    reason: str = ''

    @property
    def found(self) -> bool:
        return self.pose is not None


def fiducial_for(camera: CameraModel) -> Fiducial:
    """The pair a camera tracks: the macro pair when it spans at most half the field (the
    macro camera: 5.8 mm of 150), else the micro pair (the micro camera's 2 mm field)."""
    span = MACRO_FIDUCIAL.baseline_m + 2 * MACRO_FIDUCIAL.front.radius_m
    return MACRO_FIDUCIAL if span <= 0.5 * min(camera.field_m) else MICRO_FIDUCIAL


# Where the last pose is known, the fiducial is first looked for around it, a quarter of the
# pair's baseline beyond the pair (1 mm for the macro pair: a robot at 14 mm/s goes 0.47 mm
# between frames at 30 Hz; a faster one is found in the whole frame).
SEARCH_MARGIN_BASELINES = 0.25


def track(image: np.ndarray, camera: CameraModel, near: tuple[float, float] | None = None,
          yaw_rad: float = 0.0) -> Track:
    """The robot's pose (platform frame) in ``image`` of ``camera`` turned by ``yaw_rad`` about
    its centre, from its fiducial.

    ``near``: where the robot was in the last frame (platform x, y). The fiducial is then first
    looked for in a window around it, and in the whole frame only if it is not found there
    whole (a quarter of the micro camera's frame, 67 x 54 of the macro camera's 1280 x 1024
    pixels: most of the tracker's time per frame was the whole frame's histogram).

    Raises
    ------
    CameraConfigError
        If ``image`` is not a 2-D array of the camera's resolution (a corrupt frame).
    """
    columns, rows = (int(v) for v in camera.resolution_px)
    if image.ndim != 2 or image.shape != (rows, columns):
        raise CameraConfigError(f'{camera.name}: expected a {columns} x {rows} mono image, got '
                                f'shape {image.shape}')
    fiducial = fiducial_for(camera)
    found = _track_in_camera_frame(
        image, camera, fiducial,
        None if near is None else camera_frame(camera, yaw_rad, near[0], near[1], 0.0)[:2])
    if found.pose is None or not yaw_rad:
        return found
    return Track(platform_frame(camera, yaw_rad, *found.pose))


def _track_in_camera_frame(image: np.ndarray, camera: CameraModel, fiducial: Fiducial,
                           near: tuple[float, float] | None) -> Track:
    columns, rows = (int(v) for v in camera.resolution_px)
    if near is not None:
        px, py = camera.pixel_size_m
        reach = ((0.5 + SEARCH_MARGIN_BASELINES) * fiducial.baseline_m
                 + fiducial.front.radius_m)
        column = (near[0] - (camera.center_m[0] - camera.field_m[0] / 2)) / px
        row = (camera.center_m[1] + camera.field_m[1] / 2 - near[1]) / py
        region = (max(0, int(row - reach / py)), min(rows, int(row + reach / py) + 1),
                  max(0, int(column - reach / px)), min(columns, int(column + reach / px) + 1))
        if region[1] - region[0] > 8 and region[3] - region[2] > 8:
            found = _locate(image, camera, fiducial, region)
            if found.found:
                return found
    return _locate(image, camera, fiducial, (0, rows, 0, columns))


def _locate(image: np.ndarray, camera: CameraModel, fiducial: Fiducial,
            region: tuple[int, int, int, int]) -> Track:
    """The fiducial in ``region`` (first row, end row, first column, end column) of ``image``;
    a blob touching the region's border is cut (by the field's edge when the region is the
    whole frame)."""
    import cv2

    columns, rows = (int(v) for v in camera.resolution_px)
    r0, r1, c0, c1 = region
    part = image[r0:r1, c0:c1]
    px, py = camera.pixel_size_m
    # The surround as the median level, the peak as the tenth brightest pixel: both from the
    # histogram (one pass over the frame, no sort or float copy of a megapixel).
    full_scale = int(np.iinfo(image.dtype).max)
    histogram = cv2.calcHist([part], [0], None, [full_scale + 1], [0, full_scale + 1]).ravel()
    cumulative = np.cumsum(histogram)
    background = float(np.searchsorted(cumulative, 0.5 * cumulative[-1]))
    peak = float(np.searchsorted(cumulative, cumulative[-1] - 10))
    if peak - background < 0.2 * full_scale * (DOT_LEVEL - PLATFORM_LEVEL):
        return Track(reason='no fiducial: nothing brighter than the platform')
    threshold = 0.5 * (background + peak)
    binary = np.asarray(cv2.compare(part, np.array([threshold]), cv2.CMP_GT))
    # Blobs as outer contours (a few on a megapixel: far cheaper than labelling every pixel);
    # a blob's area is its pixels above the threshold inside its bounding box.
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    # In frame pixels: the region's offset added.
    boxes = [(left + c0, top + r0, width, height) for left, top, width, height in
             (cv2.boundingRect(contour) for contour in contours)]
    expected = {name: math.pi * dot.radius_m ** 2 / (px * py)
                for name, dot in (('front', fiducial.front), ('back', fiducial.back))}
    found: dict[str, list[int]] = {'front': [], 'back': []}
    cut: dict[str, int] = {'front': 0, 'back': 0}
    largest = 1.6 * max(expected.values())
    for label, (left, top, width, height) in enumerate(boxes):
        if width * height * 0.5 > 4 * largest:
            continue   # far larger than a dot, whatever it holds
        area = cv2.countNonZero(binary[top - r0:top - r0 + height, left - c0:left - c0 + width])
        at_edge = left == c0 or top == r0 or left + width >= c1 or top + height >= r1
        for name, size in expected.items():
            # A blob at the edge is only part of what it is: never taken, only counted.
            if at_edge and area <= 1.6 * size:
                cut[name] += 1
            elif 0.5 * size <= area <= 1.6 * size:
                found[name].append(label)
    missing = [name for name in ('front', 'back') if not found[name]]
    if missing and any(cut[name] for name in missing):
        return Track(reason=f'fiducial cut by the edge of the {camera.name} field')
    if missing:
        sizes = ', '.join(f'{expected[name]:.0f} px' for name in missing)
        return Track(reason=f'fiducial not found: no {" or ".join(missing)} dot of the '
                            f'expected size ({sizes})')
    if len(found['front']) > 1 or len(found['back']) > 1:
        return Track(reason=f'ambiguous: {len(found["front"])} front and {len(found["back"])} '
                            'back dot candidates')
    centres = {}
    for name in ('front', 'back'):
        left, top, width, height = boxes[found[name][0]]
        pad = max(2, round(1.5 * min(width, height) / 4) + 2)
        y0, y1 = max(0, top - pad), min(rows, top + height + pad)
        x0, x1 = max(0, left - pad), min(columns, left + width + pad)
        window = image[y0:y1, x0:x1].astype(np.float32)
        # Intensity-weighted centroid above the local surround (the chassis around the dot).
        surround = float(np.median(np.concatenate([window[0], window[-1], window[:, 0],
                                                   window[:, -1]])))
        weights = np.clip(window - surround, 0.0, None)
        total = float(weights.sum())
        if total <= 0.0:
            return Track(reason=f'{name} dot has no contrast')
        rows_index, columns_index = np.mgrid[y0:y1, x0:x1]
        u = float((weights * columns_index).sum() / total) + 0.5
        v = float((weights * rows_index).sum() / total) + 0.5
        centres[name] = (camera.center_m[0] - camera.field_m[0] / 2 + u * px,
                         camera.center_m[1] + camera.field_m[1] / 2 - v * py)
    (fx, fy), (bx, by) = centres['front'], centres['back']
    # The dots sit symmetrically about the centre on the robot's X axis.
    offset = 0.5 * (fiducial.front.x_m + fiducial.back.x_m)
    heading = math.atan2(fy - by, fx - bx)
    return Track((0.5 * (fx + bx) - offset * math.cos(heading),
                  0.5 * (fy + by) - offset * math.sin(heading), heading))


class ImageLike(Protocol):
    """What a sensor_msgs/Image carries, whoever decoded it (rclpy, or rosbags from a bag)."""

    encoding: str
    width: int
    height: int
    step: int
    is_bigendian: int
    data: Any


DTYPES = {'mono8': np.uint8, 'mono16': np.uint16}


def image_array(msg: ImageLike, expected: tuple[int, int] | None) -> np.ndarray:
    """The pixels of ``msg`` (a sensor_msgs/Image, from rclpy or read from a bag) as a rows x
    columns array; a native little-endian frame without row padding is not copied.

    Raises
    ------
    CameraConfigError
        Naming what is wrong: the encoding, the size against the CameraInfo, the data length.
    """
    if msg.encoding not in DTYPES:
        raise CameraConfigError(f'encoding {msg.encoding!r} is not mono8 or mono16')
    if expected is not None and (msg.width, msg.height) != expected:
        raise CameraConfigError(f'image is {msg.width} x {msg.height}, its CameraInfo says '
                                f'{expected[0]} x {expected[1]}')
    dtype = np.dtype(DTYPES[msg.encoding]).newbyteorder('>' if msg.is_bigendian else '<')
    row_bytes = msg.width * dtype.itemsize
    if msg.step < row_bytes or len(msg.data) != msg.step * msg.height:
        raise CameraConfigError(f'{len(msg.data)} bytes of data for {msg.height} rows of step '
                                f'{msg.step} ({msg.width} pixels of {dtype.itemsize} bytes)')
    rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)
    pixels = rows[:, :row_bytes]
    if msg.step != row_bytes:
        pixels = pixels.copy()    # padded rows: the view needs contiguous rows
    # A native little-endian mono8/mono16 frame is used as it is, with no copy.
    return pixels.view(dtype).astype(DTYPES[msg.encoding], copy=False)
