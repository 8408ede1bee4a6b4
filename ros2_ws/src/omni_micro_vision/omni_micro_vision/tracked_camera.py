"""One camera as the tracker reads it: where its pixels lie on the platform, what its captures
state, and whether a driver's CameraInfo agrees with that.

The settings are ``tracker_node``'s parameters under ``<name>.`` (its section of the graph's params
file), read the same way by the node and by ``omni-micro track``. With ``<name>.calibration.*``
(what ``omni-micro calibrate-camera`` writes) the pixels go through that calibration, lens
included; without it through the nominal geometry (``center_m``, ``field_m``, ``resolution_px``,
``yaw_rad``, ``mirrored``: an ideal camera, the simulated one). No rclpy.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel, checked_yaw
from omni_micro_vision.encodings import checked_bit_depth
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fiducial import fiducial_for
from omni_micro_vision.geometry import Lens, PlaneMap

# What calibrate-camera writes under <name>.calibration (empty: no calibration).
CALIBRATION_KEYS = ('resolution_px', 'camera_matrix', 'distortion', 'homography', 'residual_px',
                    'residual_m')
# A CameraInfo's fx / fy may differ from the nominal pixels' aspect by this much.
ASPECT_TOLERANCE = 0.01


@dataclass(frozen=True)
class TrackedCamera:
    """A camera's map to the platform and the spread its captures state."""

    plane: PlaneMap
    calibrated: bool
    noise_px: float
    quantisation_px: float
    bit_depth: int

    @functools.cached_property
    def model(self) -> CameraModel:
        """Its measurement model (vision_node's), with the baseline of the pair it tracks."""
        model = self.plane.camera_model(self.noise_px, self.quantisation_px)
        return dataclasses.replace(model, marker_baseline_m=fiducial_for(model).baseline_m)

    def uncertainty(self, phi_rad: float) -> CaptureUncertainty:
        """The spread a capture states: the pixel noise (vision_node's model) and the
        calibration's residual on the platform, which each dot's position carries too."""
        model = self.model
        pixel = model.uncertainty(phi_rad)
        residual = self.plane.residual_m
        # The midpoint of two dots: their residuals halve in variance; the heading sees their
        # difference across the baseline.
        return CaptureUncertainty(
            math.hypot(pixel.x_sigma_m, residual / math.sqrt(2.0)),
            math.hypot(pixel.y_sigma_m, residual / math.sqrt(2.0)),
            math.hypot(pixel.heading_sigma_rad, residual / model.marker_baseline_m))

    def refusal(self, width: int, height: int, camera_matrix: Sequence[float],
                distortion: Sequence[float]) -> str | None:
        """Why frames that come with this CameraInfo cannot be tracked (None: they can)."""
        columns, rows = self.plane.resolution_px
        what = 'calibration' if self.calibrated else 'nominal geometry (no calibration)'
        if (width, height) != (columns, rows):
            return (f'CameraInfo says {width} x {height} pixels, the {what} is for '
                    f'{columns} x {rows}')
        try:
            lens = Lens(tuple(camera_matrix), tuple(distortion))
        except CameraConfigError as error:
            return f'CameraInfo is not usable: {error}'
        if self.calibrated:
            if lens.differs(self.plane.lens):
                return (f'CameraInfo K {_short(lens.camera_matrix)} D '
                        f'{_short(lens.distortion)} differs from the calibrated K '
                        f'{_short(self.plane.lens.camera_matrix)} D '
                        f'{_short(self.plane.lens.distortion)}: calibrate again '
                        f'(omni-micro calibrate-camera)')
            return None
        if lens.distorts:
            return (f'CameraInfo has lens distortion D {_short(lens.distortion)} and '
                    f'{self.plane.name} has no calibration: run omni-micro calibrate-camera')
        if lens.calibrated:
            px, py = self.plane.pixel_size_m
            fx, fy = lens.camera_matrix[0], lens.camera_matrix[4]
            # fx * px = fy * py for a camera square to the platform.
            if abs(fx * px / (fy * py) - 1.0) > ASPECT_TOLERANCE:
                return (f'CameraInfo fx/fy = {fx / fy:.4g}, but the nominal field and '
                        f'resolution make pixels of {px * 1e6:.4g} x {py * 1e6:.4g} um (fx/fy '
                        f'{py / px:.4g}): set field_m, or calibrate (omni-micro '
                        f'calibrate-camera)')
        return None


def _short(values: Sequence[float]) -> str:
    return '[' + ', '.join(f'{v:.6g}' for v in values) + ']'


Setting = Callable[[str, Any], Any]


def tracked_camera(name: str, setting: Setting) -> TrackedCamera:
    """Camera ``name`` from its settings: ``setting(key, default)`` gives the value of
    ``<name>.<key>`` (a node's parameter, or a params file's entry).

    Raises
    ------
    CameraConfigError
        Naming the setting that is wrong.
    """
    default: CameraModel = getattr(DEFAULT_RIG, name)

    def get(key: str, fallback: object) -> Any:
        return setting(f'{name}.{key}', fallback)

    noise = get('noise_px', default.noise_px)
    quantisation = get('quantisation_px', default.quantisation_px)
    bit_depth = checked_bit_depth(f'{name}.bit_depth', get('bit_depth', 0))
    calibration = {key: get(f'calibration.{key}', None) for key in CALIBRATION_KEYS}
    nominal = CameraModel(name, get('center_m', list(default.center_m)),
                          get('field_m', list(default.field_m)),
                          get('resolution_px', [int(v) for v in default.resolution_px]),
                          noise, quantisation)
    yaw = checked_yaw(f'{name}.yaw_rad', get('yaw_rad', 0.0))
    mirrored = get('mirrored', False)
    if not isinstance(mirrored, bool):
        raise CameraConfigError(f'{name}.mirrored must be true or false, got {mirrored!r}')
    if not calibration['homography']:
        plane = PlaneMap.nominal(nominal, yaw, mirrored)
        return TrackedCamera(plane, False, nominal.noise_px, nominal.quantisation_px, bit_depth)
    missing = [key for key in ('resolution_px', 'camera_matrix') if not calibration[key]]
    if missing:
        raise CameraConfigError(f'{name}.calibration has a homography but no '
                                f'{" or ".join(missing)}: use the file calibrate-camera wrote')
    plane = PlaneMap(name, tuple(calibration['resolution_px']),
                     tuple(calibration['homography']),
                     Lens(tuple(calibration['camera_matrix']),
                          tuple(calibration['distortion'] or ())),
                     float(calibration['residual_px'] or 0.0),
                     float(calibration['residual_m'] or 0.0))
    if plane.mirrored != mirrored:
        raise CameraConfigError(
            f'{name}.mirrored is {str(mirrored).lower()} but the calibration maps a '
            f'{"mirrored" if plane.mirrored else "plain"} image: calibrate again with '
            f'--mirrored as the camera is')
    return TrackedCamera(plane, True, nominal.noise_px, nominal.quantisation_px, bit_depth)
