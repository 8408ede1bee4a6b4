"""One simulated camera's frames as a driver sends them: the bytes of each sensor_msgs/Image
and of its CameraInfo, of the robot or of a calibration target.

``camera_node`` publishes them; ``omni-micro record-target`` writes them to a bag: the same
bytes. A frame is a function of (seed, camera, frame number) and what the camera sees.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel, checked_yaw
from omni_micro_vision.image_messages import ImageWriter
from omni_micro_vision.optics import WORKING_DISTANCE_M, CameraOptics
from omni_micro_vision.rendering import InView, Sensor, expose, render_robots, warm_up
from omni_micro_vision.targets import DEFAULT_TARGET, TARGET_KINDS, Target, render_target

# What the cameras show: the robot, or a calibration target lying on the platform.
SCENES = ('robot', *TARGET_KINDS)


class CameraFrames:
    """Camera ``optics`` with ``sensor``, the ``index``-th of the rig (its noise is seeded by
    (seed, index, frame number)), showing the robot or, with ``target``, that target."""

    def __init__(self, index: int, optics: CameraOptics, sensor: Sensor, seed: int,
                 target: Target | None = None) -> None:
        self.index = index
        self.optics = optics
        self.sensor = sensor
        self.seed = seed
        self.target = target
        columns, rows = (int(v) for v in optics.camera.resolution_px)
        self.writer = ImageWriter(f'{optics.camera.name}_optical_frame', rows, columns,
                                  sensor.encoding, optics.lens)

    @functools.cached_property
    def _target_reflectance(self) -> np.ndarray:
        assert self.target is not None
        return render_target(self.optics.camera, self.target, self.optics.yaw_rad)

    def pixels(self, number: int, scene: RobotState | Sequence[InView]) -> np.ndarray:
        """Frame ``number`` of a robot whose motion at the exposure's start is ``scene``, or of
        a fleet's robots (each where it was then, with its code)."""
        rng = np.random.default_rng([self.seed, self.index, number])
        if self.target is None:
            robots = [InView(scene)] if isinstance(scene, RobotState) else list(scene)
            ideal = render_robots(self.optics.camera, self.sensor, robots, rng,
                                  self.optics.yaw_rad)
        else:
            ideal = expose(self._target_reflectance, self.sensor, rng)
        return self.optics.view(ideal)

    def messages(self, number: int, sec: int, nanosec: int,
                 scene: RobotState | Sequence[InView]) -> tuple[bytes, bytes]:
        """The CameraInfo and the Image of frame ``number`` (of ``scene``, as
        :meth:`pixels`), stamped (sec, nanosec)."""
        return (self.writer.info(sec, nanosec),
                self.writer.image(sec, nanosec, self.pixels(number, scene)))

    def warm_up(self) -> None:
        """What the first frame would otherwise pay inside the loop's time: the scene kernel,
        the flat fields, the target, the lens's map."""
        if self.target is None:
            warm_up(self.optics.camera, self.sensor, self.optics.yaw_rad)
        else:
            _ = self._target_reflectance
        self.optics.prepare()


Setting = Callable[[str, Any], Any]


def camera_settings(name: str, setting: Setting) -> tuple[CameraOptics, Sensor]:
    """Camera ``name``'s mount, lens and sensor from camera_node's parameters:
    ``setting(key, default)`` gives the value of ``<name>.<key>`` (a declared parameter, or a
    params file's entry).

    Raises
    ------
    CameraConfigError
        Naming the setting that is wrong.
    """
    default: CameraModel = getattr(DEFAULT_RIG, name)
    camera = CameraModel(name, setting(f'{name}.center_m', list(default.center_m)),
                         setting(f'{name}.field_m', list(default.field_m)),
                         setting(f'{name}.resolution_px',
                                 [int(v) for v in default.resolution_px]))
    optics = CameraOptics(
        camera, checked_yaw(f'{name}.yaw_rad', setting(f'{name}.yaw_rad', 0.0)),
        setting(f'{name}.mirrored', False),
        setting(f'{name}.working_distance_m', WORKING_DISTANCE_M[name]),
        tuple(setting(f'{name}.distortion', [0.0, 0.0])))
    defaults = Sensor()
    sensor = Sensor(**{field: setting(f'{name}.{field}', getattr(defaults, field))
                       for field in ('psf_sigma_px', 'full_well_e', 'read_noise_e', 'bit_depth',
                                     'exposure_s')})
    return optics, sensor


def target_settings(kind: str, setting: Setting) -> Target:
    """The calibration target of ``kind`` (chessboard, circles) from camera_node's
    ``target.*`` parameters."""
    target: Target = TARGET_KINDS[kind](
        tuple(setting('target.pattern', list(DEFAULT_TARGET.pattern))),
        setting('target.pitch_m', DEFAULT_TARGET.pitch_m),
        tuple(setting('target.center_m', list(DEFAULT_TARGET.center_m))),
        setting('target.yaw_rad', DEFAULT_TARGET.yaw_rad))
    return target
