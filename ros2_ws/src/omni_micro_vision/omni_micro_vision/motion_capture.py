"""A camera that captures a moving robot: when each frame is exposed and when its capture is
ready, what the motion blur does to the capture's spread, and how fast the robot may go before
the tracker loses it. No rclpy.

**Timing** (:class:`CameraTiming`). Frame k is exposed from ``k / frame_rate_hz`` for
``exposure_s``; its capture is stamped at the exposure's middle and is ready ``delay_s`` after
the exposure ends, plus a jitter drawn from [0, ``jitter_s``] per frame (a function of the
seed, the camera and the frame: the same run at any speed).

**Blur** (:func:`uncertainty_in_motion`). During the exposure each printed dot moves by
``l = speed * exposure_s``: its image is the dot convolved with a segment of
that length. The tracker's centroid of that streak is the dot's centroid at mid-exposure
(the segment is symmetric about it), so a capture in motion is stamped there and is unbiased
at constant velocity. Its noise grows along the travel only: the centroid's variance is the
image's second moment over the photons collected, and the streak's second moment along the
travel is the dot's, ``R^2 / 4`` for a disc of radius ``R``, plus the segment's, ``l^2 / 12``,
with the same photons (the exposure does not change). So along the travel::

    sigma_moving = sigma_still * sqrt(1 + l^2 / (3 R^2))

with ``R`` the radius of the smaller dot of the camera's pair; across it the spread is the still
one. An acceleration ``a`` during the exposure moves the streak's centroid off the mid-exposure
pose by ``a * exposure_s^2 / 24`` (the mean of ``a t^2 / 2`` over the exposure), which the
stated spread includes as a bound.

**Loss.** Once the streak is longer than ``MAX_BLUR_PER_DOT_RADIUS`` of that dot's radii, the
dots are no longer the sizes the tracker looks for: measured on rendered frames
(docs/images.md, "Captures in motion"), the macro camera's tracker finds no pose at 2.4 radii
and the micro camera's spread grows five-fold at 1.8. Such frames give no capture.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_vision.camera import CameraModel, CameraRig, CaptureRule
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fiducial import fiducial_for
from omni_micro_vision.rendering import Sensor

# The longest streak, in radii of the smaller dot, at which the rendered frames' tracker still
# finds every frame with its still spread (measured: the macro camera to 1.6 radii, the micro
# camera to 1.37; lost at 2.4 and five times the spread at 1.8).
MAX_BLUR_PER_DOT_RADIUS = 1.4


@dataclass(frozen=True)
class CameraTiming:
    """When a camera exposes its frames and when their captures are ready (seconds)."""

    # By default the stationary captures' frame rate and the rendered camera's exposure.
    frame_rate_hz: float = CaptureRule.frame_rate_hz
    exposure_s: float = Sensor.exposure_s
    delay_s: float = 0.0
    jitter_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ('frame_rate_hz', 'exposure_s', 'delay_s', 'jitter_s'):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value) or value < 0.0 \
                    or (name == 'frame_rate_hz' and value == 0.0):
                raise CameraConfigError(f'{name} must be a finite number '
                                        f'{"> 0" if name == "frame_rate_hz" else ">= 0"}, got '
                                        f'{value!r}')
            object.__setattr__(self, name, float(value))
        if self.exposure_s * self.frame_rate_hz > 1.0:
            raise CameraConfigError(f'exposure_s {self.exposure_s!r} is longer than a frame at '
                                    f'{self.frame_rate_hz!r} Hz')

    def exposure_start_s(self, frame: int) -> float:
        return frame / self.frame_rate_hz

    def stamp_s(self, frame: int) -> float:
        """The capture's stamp: the middle of its exposure."""
        return self.exposure_start_s(frame) + 0.5 * self.exposure_s

    def ready_s(self, frame: int, seed: int, camera: str) -> float:
        """When the capture of ``frame`` is ready: the exposure's end, the delay and this frame's
        jitter (the same for the same seed, camera and frame)."""
        jitter = 0.0
        if self.jitter_s > 0.0:
            rng = np.random.default_rng(np.random.SeedSequence(
                [seed, sum(camera.encode()), frame]))
            jitter = float(rng.uniform(0.0, self.jitter_s))
        return self.exposure_start_s(frame) + self.exposure_s + self.delay_s + jitter

    def first_frame_after(self, time_s: float) -> int:
        """The first frame whose exposure starts at or after ``time_s``."""
        return max(0, math.ceil(time_s * self.frame_rate_hz - 1e-9))


def capture_age_bound_s(timings: Iterable[CameraTiming], period_s: float) -> float:
    """The oldest a capture in motion can be when it is released on a grid of ``period_s``:
    half an exposure, the delay and the whole jitter, and one period (the first sample at or
    after it is ready). A capture waiting for an earlier frame's is no older (that one was)."""
    return max((0.5 * timing.exposure_s + timing.delay_s + timing.jitter_s
                for timing in timings), default=0.0) + period_s


def dot_radius_m(camera: CameraModel) -> float:
    """The radius of the smaller dot of the pair ``camera`` tracks."""
    fiducial = fiducial_for(camera)
    return min(fiducial.front.radius_m, fiducial.back.radius_m)


def blur_m(speed_m_s: float, exposure_s: float) -> float:
    """How far the robot moves during one exposure: the streak's length."""
    return abs(speed_m_s) * exposure_s


def trackable(camera: CameraModel, speed_m_s: float, exposure_s: float) -> bool:
    """Whether the tracker still finds the robot moving at ``speed_m_s`` (see the module)."""
    return blur_m(speed_m_s, exposure_s) <= MAX_BLUR_PER_DOT_RADIUS * dot_radius_m(camera)


def max_trackable_speed_m_s(camera: CameraModel, exposure_s: float) -> float:
    """The fastest the robot may move and still be captured by ``camera``."""
    if exposure_s <= 0.0:
        return math.inf
    return MAX_BLUR_PER_DOT_RADIUS * dot_radius_m(camera) / exposure_s


def along_travel_factor(camera: CameraModel, speed_m_s: float, exposure_s: float) -> float:
    """``sigma_moving / sigma_still`` along the travel: sqrt(1 + l^2 / (3 R^2))."""
    ratio = blur_m(speed_m_s, exposure_s) / dot_radius_m(camera)
    return math.sqrt(1.0 + ratio * ratio / 3.0)


def uncertainty_in_motion(camera: CameraModel, phi_rad: float, vx_m_s: float, vy_m_s: float,
                          exposure_s: float, acceleration_m_s2: float = 0.0,
                          still: CaptureUncertainty | None = None) -> CaptureUncertainty:
    """The spread of a capture of a robot heading ``phi_rad`` moving at (vx, vy), stamped at
    mid-exposure: the still spread (``camera``'s model, or ``still`` as a tracker states it),
    grown along the travel by :func:`along_travel_factor`, and the acceleration's shift of the
    streak (``a * exposure^2 / 24``) added as a bound. x and y are the diagonal of the rotated
    covariance."""
    still = still or camera.uncertainty(phi_rad)
    speed = math.hypot(vx_m_s, vy_m_s)
    if speed == 0.0 and acceleration_m_s2 == 0.0:
        return still
    factor = along_travel_factor(camera, speed, exposure_s)
    cos, sin = (vx_m_s / speed, vy_m_s / speed) if speed > 0.0 else (1.0, 0.0)
    # Still covariance, diagonal in x and y; grown by factor^2 along (cos, sin).
    var_x, var_y = still.x_sigma_m ** 2, still.y_sigma_m ** 2
    along = var_x * cos * cos + var_y * sin * sin
    extra = (factor * factor - 1.0) * along
    shift = abs(acceleration_m_s2) * exposure_s * exposure_s / 24.0
    return CaptureUncertainty(
        math.sqrt(var_x + extra * cos * cos + (shift * cos) ** 2),
        math.sqrt(var_y + extra * sin * sin + (shift * sin) ** 2),
        still.heading_sigma_rad)


def measure_in_motion(camera: CameraModel, x_m: float, y_m: float, phi_rad: float,
                      vx_m_s: float, vy_m_s: float, exposure_s: float,
                      rng: np.random.Generator) -> tuple[float, float, float]:
    """A capture of the robot whose pose at mid-exposure is (x, y, phi), moving at (vx, vy):
    the still measurement, and the extra spread along the travel that the blur adds."""
    x, y, phi = camera.measure(x_m, y_m, phi_rad, rng)
    speed = math.hypot(vx_m_s, vy_m_s)
    if speed == 0.0:
        return x, y, phi
    still = camera.uncertainty(phi_rad)
    cos, sin = vx_m_s / speed, vy_m_s / speed
    along = math.sqrt(still.x_sigma_m ** 2 * cos * cos + still.y_sigma_m ** 2 * sin * sin)
    factor = along_travel_factor(camera, speed, exposure_s)
    extra = along * math.sqrt(factor * factor - 1.0) * float(rng.standard_normal())
    return x + extra * cos, y + extra * sin, phi


# The noise of captures in motion is drawn from its own stream, apart from the stationary
# captures' (seed, stop, frame): adding captures in motion changes no stationary capture.
_MOTION_STREAM = 0x6D6F74


@dataclass(frozen=True)
class MotionCapture:
    """A capture of the moving robot: stamped at mid-exposure, published once ``ready_s``."""

    stamp_s: float
    ready_s: float
    x_m: float
    y_m: float
    phi_rad: float
    camera: str
    frame: int
    uncertainty: CaptureUncertainty


class MovingCamera:
    """Turns the robot's true motion (odometry samples, in stamp order) into captures of it in
    motion, per camera at its own rate: a frame whose exposure's middle falls between two samples
    sees the robot where the samples put it then (linear between them: at most a * dt^2 / 8, 4 nm
    for the motors' acceleration over the 20 ms grid), in the finest camera that holds it and can
    follow it at that speed (the macro camera where the micro one cannot). A robot that stands
    still is the stationary captures' (:class:`omni_micro_vision.camera.StationaryCamera`); a
    capture is released once the samples have reached its ``ready_s``.
    """

    def __init__(self, rig: CameraRig, timings: dict[str, CameraTiming], seed: int = 0,
                 still_speed_m_s: float = 1.0e-6) -> None:
        self.rig = rig
        self.timings = timings
        self.seed = int(seed)
        self.still_speed_m_s = still_speed_m_s
        self._last: tuple[float, np.ndarray] | None = None
        self._next_frame = {name: 0 for name in timings}
        self._pending: list[MotionCapture] = []

    def on_odometry(self, stamp_s: float, x_m: float, y_m: float, phi_rad: float,
                    vx_m_s: float, vy_m_s: float) -> list[MotionCapture]:
        """Feed one sample; return the captures ready by its stamp, in stamp order."""
        sample = np.array([x_m, y_m, phi_rad, vx_m_s, vy_m_s])
        last, self._last = self._last, (stamp_s, sample)
        if last is not None and stamp_s > last[0]:
            for name, timing in self.timings.items():
                self._expose(name, timing, last, (stamp_s, sample))
        self._pending.sort(key=lambda c: (c.stamp_s, c.camera))
        # In exposure order: the first not ready holds back every later one.
        waiting = next((index for index, c in enumerate(self._pending)
                        if c.ready_s > stamp_s + 1e-9), len(self._pending))
        ready, self._pending = self._pending[:waiting], self._pending[waiting:]
        return ready

    def _expose(self, name: str, timing: CameraTiming, before: tuple[float, np.ndarray],
                after: tuple[float, np.ndarray]) -> None:
        (t0, a), (t1, b) = before, after
        frame = max(self._next_frame[name],
                    timing.first_frame_after(t0 - 0.5 * timing.exposure_s))
        while timing.stamp_s(frame) <= t1 + 1e-12:
            middle = timing.stamp_s(frame)
            if middle > t0:
                share = (middle - t0) / (t1 - t0)
                x, y, _, vx, vy = a + share * (b - a)
                phi = a[2] + share * math.remainder(b[2] - a[2], 2 * math.pi)
                acceleration = math.hypot(b[3] - a[3], b[4] - a[4]) / (t1 - t0)
                self._capture(name, timing, frame, middle, (x, y, phi), (vx, vy), acceleration)
            frame += 1
        self._next_frame[name] = frame

    def _speaker(self, x_m: float, y_m: float, speed_m_s: float) -> CameraModel | None:
        """The finest camera that holds the robot and can follow it at this speed."""
        for camera in (self.rig.micro, self.rig.macro):
            timing = self.timings.get(camera.name)
            if timing is not None and camera.contains(x_m, y_m) \
                    and trackable(camera, speed_m_s, timing.exposure_s):
                return camera
        return None

    def _capture(self, name: str, timing: CameraTiming, frame: int, middle: float,
                 pose: tuple[float, float, float], velocity: tuple[float, float],
                 acceleration: float) -> None:
        (x, y, phi), (vx, vy) = pose, velocity
        speed = math.hypot(vx, vy)
        camera: CameraModel = getattr(self.rig, name)
        if speed < self.still_speed_m_s or self._speaker(x, y, speed) is not camera:
            return
        rng = np.random.default_rng(np.random.SeedSequence(
            [self.seed, _MOTION_STREAM, sum(name.encode()), frame]))
        measured = measure_in_motion(camera, x, y, phi, vx, vy, timing.exposure_s, rng)
        self._pending.append(MotionCapture(
            middle, timing.ready_s(frame, self.seed, name), *measured, name, frame,
            uncertainty_in_motion(camera, measured[2], vx, vy, timing.exposure_s, acceleration)))
