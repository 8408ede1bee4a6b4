"""The overhead cameras as measurement models, and the rule for when they capture.

A camera sees a rectangle of the platform through a sensor of ``resolution_px`` pixels, so one
pixel covers ``field / resolution`` metres. The robot carries two marks ``marker_baseline_m``
apart along its X axis; the tracker locates each mark with a Gaussian error of ``noise_px``
pixels and reports it on a grid of ``quantisation_px`` pixels (sub-pixel centroiding still ends
on a finite grid). The pose is the marks' midpoint and the heading of the line between them, so
the heading noise follows from the pixel size as it would on a real image.

Noise is drawn from a generator seeded by (run seed, stop index, frame index after the stop):
a capture's error depends on which capture it is, never on how many were taken before or on
timing, so the same seed gives the same run at any real-time factor.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_common.conventions import (
    MICRO_FIELD_CENTER_M,
    MICRO_FIELD_SIZE_M,
    PLATFORM_CENTER_M,
    PLATFORM_SIZE_M,
    CaptureUncertainty,
)
from omni_micro_vision.errors import CameraConfigError


def _finite(name: str, value: float, *, positive: bool = False,
            non_negative: bool = False) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise CameraConfigError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number):
        raise CameraConfigError(f'{name} must be finite, got {value!r}')
    if positive and number <= 0.0:
        raise CameraConfigError(f'{name} must be > 0, got {value!r}')
    if non_negative and number < 0.0:
        raise CameraConfigError(f'{name} must be >= 0, got {value!r}')
    return number


def _pair(name: str, values: object, **checks: bool) -> tuple[float, float]:
    items = list(values) if isinstance(values, (list, tuple)) else None
    if items is None or len(items) != 2:
        raise CameraConfigError(f'{name} must be two numbers [x, y], got {values!r}')
    return (_finite(f'{name}[0]', items[0], **checks), _finite(f'{name}[1]', items[1], **checks))


# The largest frame a camera may have: machine-vision sensors reach about 20-25 megapixels, and
# a rendered frame takes 55-90 bytes a pixel while it is drawn (100000 x 100000 asked 74.5 GiB).
MAX_SIDE_PX = 16384
MAX_PIXELS = 25_000_000


def check_resolution(name: str, resolution: tuple[float, float]) -> None:
    """Raises CameraConfigError naming ``name`` if the frame is larger than a camera's."""
    columns, rows = resolution
    if max(columns, rows) > MAX_SIDE_PX or columns * rows > MAX_PIXELS:
        raise CameraConfigError(f'{name} {[int(columns), int(rows)]} is larger than a camera: at '
                                f'most {MAX_SIDE_PX} a side and {MAX_PIXELS / 1e6:g} megapixels')


@dataclass(frozen=True)
class CameraModel:
    """One overhead camera: where it looks, its pixels and its tracker's accuracy."""

    name: str
    center_m: tuple[float, float]
    field_m: tuple[float, float]
    resolution_px: tuple[float, float] = (1280, 1024)
    noise_px: float = 0.1
    quantisation_px: float = 0.1
    marker_baseline_m: float = 4.0e-3

    def __post_init__(self) -> None:
        object.__setattr__(self, 'center_m', _pair(f'{self.name}.center_m', self.center_m))
        object.__setattr__(self, 'field_m',
                           _pair(f'{self.name}.field_m', self.field_m, positive=True))
        resolution = _pair(f'{self.name}.resolution_px', self.resolution_px, positive=True)
        if any(value != int(value) for value in resolution):
            raise CameraConfigError(
                f'{self.name}.resolution_px must be whole pixels, got {self.resolution_px!r}')
        check_resolution(f'{self.name}.resolution_px', resolution)
        object.__setattr__(self, 'resolution_px', resolution)
        object.__setattr__(self, 'noise_px',
                           _finite(f'{self.name}.noise_px', self.noise_px, non_negative=True))
        object.__setattr__(self, 'quantisation_px', _finite(
            f'{self.name}.quantisation_px', self.quantisation_px, non_negative=True))
        object.__setattr__(self, 'marker_baseline_m', _finite(
            f'{self.name}.marker_baseline_m', self.marker_baseline_m, positive=True))

    @property
    def pixel_size_m(self) -> tuple[float, float]:
        return (self.field_m[0] / self.resolution_px[0], self.field_m[1] / self.resolution_px[1])

    @property
    def mark_sigma_px(self) -> float:
        """Standard deviation of one mark's position in pixels: the tracker's Gaussian error
        plus the rounding to the sub-pixel grid (uniform, variance q^2 / 12)."""
        return math.sqrt(self.noise_px ** 2 + self.quantisation_px ** 2 / 12.0)

    def uncertainty(self, phi_rad: float) -> CaptureUncertainty:
        """The analytic spread of a capture of a robot heading ``phi_rad`` (see
        :class:`CaptureUncertainty`); tests/vision checks it against sampled captures."""
        sigma_x = self.mark_sigma_px * self.pixel_size_m[0]
        sigma_y = self.mark_sigma_px * self.pixel_size_m[1]
        # The heading comes from the marks' offset across the baseline: the difference of two
        # independent mark errors, projected on the baseline's normal.
        across = math.hypot(sigma_x * math.sin(phi_rad), sigma_y * math.cos(phi_rad))
        return CaptureUncertainty(sigma_x / math.sqrt(2.0), sigma_y / math.sqrt(2.0),
                                  math.sqrt(2.0) * across / self.marker_baseline_m)

    def contains(self, x_m: float, y_m: float) -> bool:
        return (abs(x_m - self.center_m[0]) <= 0.5 * self.field_m[0]
                and abs(y_m - self.center_m[1]) <= 0.5 * self.field_m[1])

    def measure(self, x_m: float, y_m: float, phi_rad: float,
                rng: np.random.Generator) -> tuple[float, float, float]:
        """A noisy, quantised (x, y, phi) of the true pose, as the tracker would report it."""
        pixel = np.array(self.pixel_size_m)
        half = 0.5 * self.marker_baseline_m * np.array([math.cos(phi_rad), math.sin(phi_rad)])
        centre = np.array([x_m, y_m])
        origin = np.array(self.center_m) - 0.5 * np.array(self.field_m)
        marks = []
        for mark in (centre - half, centre + half):
            pixels = (mark - origin) / pixel + rng.normal(0.0, self.noise_px, 2)
            if self.quantisation_px > 0.0:
                pixels = np.round(pixels / self.quantisation_px) * self.quantisation_px
            marks.append(origin + pixels * pixel)
        middle = 0.5 * (marks[0] + marks[1])
        direction = marks[1] - marks[0]
        return float(middle[0]), float(middle[1]), math.atan2(direction[1], direction[0])


def capture_rng(seed: int, stop_index: int, frame_index: int) -> np.random.Generator:
    """The noise generator of one capture: a function of the run seed and which capture it is."""
    return np.random.default_rng(np.random.SeedSequence([seed, stop_index, frame_index]))


@dataclass(frozen=True)
class CameraRig:
    """The macro camera over the platform and the micro camera over the micro work platform.

    The micro camera is used whenever the robot is inside its field; outside the macro field
    there is no capture.
    """

    macro: CameraModel
    micro: CameraModel

    def camera_for(self, x_m: float, y_m: float) -> CameraModel | None:
        if self.micro.contains(x_m, y_m):
            return self.micro
        if self.macro.contains(x_m, y_m):
            return self.macro
        return None

    def resolution_at(self, x_m: float, y_m: float) -> tuple[str, float] | None:
        """The camera that sees a robot at (``x_m``, ``y_m``) and the 95 % radius of its
        captures there: a goal's tolerance must be wider than it to be told reached (the
        controller counts a capture reached only with that radius added). None: no camera sees
        it."""
        camera = self.camera_for(x_m, y_m)
        if camera is None:
            return None
        return camera.name, camera.uncertainty(0.0).radius_95_m


# The macro camera sees the whole platform (omni_micro_common.conventions); the micro work
# platform is centred on the goal of Fig. 11.
DEFAULT_RIG = CameraRig(
    macro=CameraModel('macro', PLATFORM_CENTER_M, PLATFORM_SIZE_M),
    micro=CameraModel('micro', MICRO_FIELD_CENTER_M, MICRO_FIELD_SIZE_M),
)


@dataclass(frozen=True)
class Capture:
    """One stationary capture: the measured pose and which capture it was."""

    stamp_s: float
    x_m: float
    y_m: float
    phi_rad: float
    camera: str
    stop_index: int
    frame_index: int
    uncertainty: CaptureUncertainty


@dataclass(frozen=True)
class OutOfField:
    """The robot stopped where no camera sees it."""

    stamp_s: float
    stop_index: int


@dataclass(frozen=True)
class CaptureRule:
    """When the cameras capture: the robot has been still for ``dwell_s``, then at frame rate.

    "Still" means every odometry sample has translation speed under ``speed_threshold_m_s`` and
    rotation speed under ``angular_threshold_rad_s``. Frame k of a stop is exposed at
    ``onset + dwell_s + k / frame_rate_hz``, where onset is the stamp of the first still sample.
    """

    speed_threshold_m_s: float = 1.0e-6
    angular_threshold_rad_s: float = 1.0e-4
    dwell_s: float = 0.02
    frame_rate_hz: float = 30.0

    def __post_init__(self) -> None:
        for name in ('speed_threshold_m_s', 'angular_threshold_rad_s', 'frame_rate_hz'):
            object.__setattr__(self, name, _finite(name, getattr(self, name), positive=True))
        object.__setattr__(self, 'dwell_s', _finite('dwell_s', self.dwell_s, non_negative=True))


class StationaryCamera:
    """Turns the robot's true motion (odometry samples, in stamp order) into captures.

    Parameters
    ----------
    rig : the two cameras.
    rule : when to capture.
    seed : run seed of the noise.
    """

    def __init__(self, rig: CameraRig = DEFAULT_RIG, rule: CaptureRule | None = None,
                 seed: int = 0) -> None:
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise CameraConfigError(f'seed must be a whole number >= 0, got {seed!r}')
        self.rig = rig
        self.rule = rule or CaptureRule()
        self.seed = int(seed)
        self.stop_index = -1
        self._onset_s: float | None = None
        self._next_frame = 0
        self._last_stamp_s = -math.inf

    @property
    def stationary(self) -> bool:
        return self._onset_s is not None

    def frame_time_s(self, frame_index: int) -> float:
        assert self._onset_s is not None
        return self._onset_s + self.rule.dwell_s + frame_index / self.rule.frame_rate_hz

    def on_odometry(self, stamp_s: float, x_m: float, y_m: float, phi_rad: float,
                    speed_m_s: float, angular_speed_rad_s: float) -> list[Capture | OutOfField]:
        """Feed one sample; return the captures (or out-of-field events) it completes."""
        if stamp_s <= self._last_stamp_s:
            return []   # a repeated or reordered sample carries nothing new
        self._last_stamp_s = stamp_s
        still = (abs(speed_m_s) < self.rule.speed_threshold_m_s
                 and abs(angular_speed_rad_s) < self.rule.angular_threshold_rad_s)
        if not still:
            self._onset_s = None
            return []
        if self._onset_s is None:
            self._onset_s = stamp_s
            self.stop_index += 1
            self._next_frame = 0
        events: list[Capture | OutOfField] = []
        # The robot is still, so the latest sample is its pose at every frame due by now.
        while self.frame_time_s(self._next_frame) <= stamp_s + 1e-9:
            frame = self._next_frame
            self._next_frame += 1
            camera = self.rig.camera_for(x_m, y_m)
            if camera is None:
                events.append(OutOfField(self.frame_time_s(frame), self.stop_index))
                continue
            measured = camera.measure(x_m, y_m, phi_rad,
                                      capture_rng(self.seed, self.stop_index, frame))
            events.append(Capture(self.frame_time_s(frame), *measured, camera.name,
                                  self.stop_index, frame, camera.uncertainty(measured[2])))
        return events


FAULT_CAMERAS = ('macro', 'micro', 'both')


@dataclass(frozen=True)
class CameraFaults:
    """Injected camera faults, to see the controller cope (all off by default).

    drop_probability : each capture is lost with this probability (drawn per capture from the
        seed, so a run still repeats).
    delay_s : each capture is published this much simulated time after its exposure.
    frozen_after_s : from this simulated time on the camera repeats its last earlier frame,
        stamp and all (a stuck driver); negative = never.
    camera : which camera misbehaves: 'macro', 'micro' or 'both'.
    """

    drop_probability: float = 0.0
    delay_s: float = 0.0
    frozen_after_s: float = -1.0
    camera: str = 'both'

    def __post_init__(self) -> None:
        probability = _finite('faults.drop_probability', self.drop_probability)
        if not 0.0 <= probability <= 1.0:
            raise CameraConfigError(
                f'faults.drop_probability must be in [0, 1], got {self.drop_probability!r}')
        object.__setattr__(self, 'drop_probability', probability)
        object.__setattr__(self, 'delay_s',
                           _finite('faults.delay_s', self.delay_s, non_negative=True))
        object.__setattr__(self, 'frozen_after_s',
                           _finite('faults.frozen_after_s', self.frozen_after_s))
        if self.camera not in FAULT_CAMERAS:
            raise CameraConfigError(
                f'faults.camera must be one of {list(FAULT_CAMERAS)}, got {self.camera!r} '
                f'(unknown camera)')


class FaultInjector:
    """Sits between the camera model and the publisher: drops, delays or freezes captures."""

    def __init__(self, faults: CameraFaults, seed: int = 0) -> None:
        self.faults = faults
        self.seed = seed
        self._held: list[Capture] = []
        self._last_good: dict[str, Capture] = {}

    def _applies(self, capture: Capture) -> bool:
        return self.faults.camera in ('both', capture.camera)

    def submit(self, capture: Capture) -> None:
        faults = self.faults
        if not self._applies(capture):
            self._held.append(capture)
            return
        if 0.0 <= faults.frozen_after_s <= capture.stamp_s:
            stale = self._last_good.get(capture.camera)
            if stale is not None:
                self._held.append(stale)
            return
        self._last_good[capture.camera] = capture
        if faults.drop_probability > 0.0:
            draw = np.random.default_rng(np.random.SeedSequence(
                [self.seed, capture.stop_index, capture.frame_index, 1])).random()
            if draw < faults.drop_probability:
                return
        self._held.append(capture)

    def due(self, now_s: float) -> list[Capture]:
        """The captures to publish at simulated time ``now_s``, in exposure order."""
        delay = self.faults.delay_s
        ready = [c for c in self._held
                 if not self._applies(c) or c.stamp_s + delay <= now_s + 1e-9]
        self._held = [c for c in self._held if c not in ready]
        return ready


# -- a camera as a node is configured: which ones, and how each is turned ------------------
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
    """A camera's turn about its centre (its image's x against the platform's): finite radians
    within +-pi, else a CameraConfigError naming ``name``."""
    try:
        angle = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise CameraConfigError(f'{name} must be a number of radians, got {value!r}') from None
    if not math.isfinite(angle) or abs(angle) > math.pi:
        raise CameraConfigError(f'{name} must be finite and within +-pi rad, got {value!r}')
    return angle


def camera_frame(camera: CameraModel, yaw_rad: float, x_m: float, y_m: float,
                 phi_rad: float) -> tuple[float, float, float]:
    """A platform pose as seen in the frame of a camera turned by ``yaw_rad`` about its
    centre (its image's x axis is the platform's x turned by yaw)."""
    cos, sin = math.cos(yaw_rad), math.sin(yaw_rad)
    dx, dy = x_m - camera.center_m[0], y_m - camera.center_m[1]
    return (camera.center_m[0] + cos * dx + sin * dy, camera.center_m[1] - sin * dx + cos * dy,
            phi_rad - yaw_rad)
