"""The fiducial printed on the robot's top: what the renderer draws and the tracker looks for.

Two white dots on the robot's X axis, the front one larger so that the heading has a sign: a
4 mm pair for the macro camera and, at the centre, a 0.6 mm pair the micro camera sees whole.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from omni_micro_sim.parameters import RobotParameters
from omni_micro_vision.camera import CameraModel


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
# The disc the dots are printed on: the nominal robot's chassis.
CHASSIS_RADIUS_M = RobotParameters().chassis_radius_m
# Reflectances: what fraction of the full well a pixel collects in one exposure (the
# tracker's threshold depends on them too).
PLATFORM_LEVEL = 0.35
CHASSIS_LEVEL = 0.12
DOT_LEVEL = 0.9


def fiducial_for(camera: CameraModel) -> Fiducial:
    """The pair a camera tracks: the macro pair when it spans at most half the field (the
    macro camera: 5.8 mm of 150), else the micro pair (the micro camera's 2 mm field)."""
    span = MACRO_FIDUCIAL.baseline_m + 2 * MACRO_FIDUCIAL.front.radius_m
    return MACRO_FIDUCIAL if span <= 0.5 * min(camera.field_m) else MICRO_FIDUCIAL
