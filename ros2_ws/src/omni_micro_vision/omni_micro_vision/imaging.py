"""Images of the robot as an overhead camera would take them, and the tracker that reads them.

No rclpy: ``camera_node`` and ``tracker_node`` (to come) are to be thin adapters of these.

**The scene.** The platform is a matte grey; the robot's top is the 9 mm dark chassis with a
printed fiducial: for the macro camera two white dots 4 mm apart on the robot's X axis (the
front one larger, so that the heading has a sign), and at the centre a smaller pair the micro
camera sees whole (0.6 mm apart). Both patterns are always there; each camera's tracker looks
for the pair whose size its pixels resolve.

**The camera.** A sensor of ``resolution_px`` pixels over the camera's field (so 117 um and
1.56 um per pixel by default), a Gaussian point spread of ``psf_sigma_px``, photon shot noise
and read noise in electrons, quantisation to ``bit_depth`` bits, and motion blur: the exposure
integrates the robot's motion over ``exposure_s``. Noise comes from a generator seeded per
frame, so a frame is a function of (seed, frame number) and the robot's motion only.

**The tracker.** Threshold halfway between the platform and the brightest dots, connected
components, the two dots picked by their expected areas, each located by its intensity-weighted
centroid (sub-pixel), and the pose from their midpoint and direction. A frame where the pair is
not found, is cut by the image's edge or is ambiguous gives no pose and says why.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim.simulator import RobotState
from omni_micro_vision.camera import CameraConfigError, CameraModel


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


def render(camera: CameraModel, sensor: Sensor, motion: RobotState,
           rng: np.random.Generator) -> np.ndarray:
    """One frame (rows x columns, uint8 or uint16) of ``camera`` seeing the robot, whose state
    (pose and velocity, platform frame) at the start of the exposure is ``motion``.

    Only the region the robot (and its motion and blur) covers is computed from the scene; the
    rest of the frame is the platform's level. Noise covers the whole frame.
    """
    import cv2

    xs, ys = pixel_centres(camera)
    px, py = camera.pixel_size_m
    pixel_m = math.sqrt(px * py)
    start, end = _pose_at(motion, 0.0), _pose_at(motion, sensor.exposure_s)
    travel_px = max(math.hypot(end[0] - start[0], end[1] - start[1]) / pixel_m,
                    abs(end[2] - start[2]) * CHASSIS_RADIUS_M / pixel_m)
    steps = int(min(32, max(1, math.ceil(travel_px / 0.5))))
    margin = CHASSIS_RADIUS_M + 4 * sensor.psf_sigma_px * pixel_m + 2 * pixel_m
    region_x = np.nonzero((xs > min(start[0], end[0]) - margin)
                          & (xs < max(start[0], end[0]) + margin))[0]
    region_y = np.nonzero((ys > min(start[1], end[1]) - margin)
                          & (ys < max(start[1], end[1]) + margin))[0]
    signal = np.full((ys.size, xs.size), PLATFORM_LEVEL, dtype=np.float32)
    if region_x.size and region_y.size:
        window = (slice(region_y[0], region_y[-1] + 1), slice(region_x[0], region_x[-1] + 1))
        wx, wy = xs[window[1]], ys[window[0]]
        patch = np.zeros((wy.size, wx.size))
        for step in range(steps):
            t = sensor.exposure_s * (step + 0.5) / steps
            patch += _reflectance(wx, wy, _pose_at(motion, t), pixel_m)
        signal[window] = (patch / steps).astype(np.float32)
    if sensor.psf_sigma_px > 0:
        signal = np.asarray(cv2.GaussianBlur(signal, (0, 0), sensor.psf_sigma_px,
                                             borderType=cv2.BORDER_REPLICATE), np.float32)
    electrons = signal * np.float32(sensor.full_well_e)
    # Shot noise (Poisson, as a Gaussian at these counts) and read noise, in one draw.
    sigma = np.sqrt(electrons + np.float32(sensor.read_noise_e ** 2))
    electrons += sigma * rng.standard_normal(electrons.shape, dtype=np.float32)
    counts = np.rint(electrons * np.float32(sensor.max_value / sensor.full_well_e))
    dtype = np.uint8 if sensor.bit_depth == 8 else np.uint16
    result: np.ndarray = np.clip(counts, 0, sensor.max_value).astype(dtype)
    return result


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


def track(image: np.ndarray, camera: CameraModel) -> Track:
    """The robot's pose in ``image`` of ``camera``, from its fiducial.

    Raises
    ------
    CameraConfigError
        If ``image`` is not a 2-D array of the camera's resolution (a corrupt frame).
    """
    import cv2

    columns, rows = (int(v) for v in camera.resolution_px)
    if image.ndim != 2 or image.shape != (rows, columns):
        raise CameraConfigError(f'{camera.name}: expected a {columns} x {rows} mono image, got '
                                f'shape {image.shape}')
    fiducial = fiducial_for(camera)
    px, py = camera.pixel_size_m
    frame = image.astype(np.float32)
    # The surround from every fourth pixel each way; the peak as the tenth brightest pixel (a
    # partition, not a sort: a few ms on a megapixel).
    background = float(np.median(frame[::4, ::4]))
    peak = float(np.partition(frame.ravel(), -10)[-10])
    if peak - background < 0.2 * float(np.iinfo(image.dtype).max) * (DOT_LEVEL - PLATFORM_LEVEL):
        return Track(reason='no fiducial: nothing brighter than the platform')
    threshold = 0.5 * (background + peak)
    binary = (frame > threshold).astype(np.uint8)
    count, _, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    expected = {name: math.pi * dot.radius_m ** 2 / (px * py)
                for name, dot in (('front', fiducial.front), ('back', fiducial.back))}
    found: dict[str, list[int]] = {'front': [], 'back': []}
    cut: dict[str, int] = {'front': 0, 'back': 0}
    for label in range(1, count):
        area = stats[label, cv2.CC_STAT_AREA]
        left, top, width, height = (int(stats[label, k]) for k in (
            cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        at_edge = left == 0 or top == 0 or left + width >= columns or top + height >= rows
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
        label = found[name][0]
        left, top, width, height = (int(stats[label, k]) for k in (
            cv2.CC_STAT_LEFT, cv2.CC_STAT_TOP, cv2.CC_STAT_WIDTH, cv2.CC_STAT_HEIGHT))
        pad = max(2, round(1.5 * min(width, height) / 4) + 2)
        y0, y1 = max(0, top - pad), min(rows, top + height + pad)
        x0, x1 = max(0, left - pad), min(columns, left + width + pad)
        window = frame[y0:y1, x0:x1]
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
