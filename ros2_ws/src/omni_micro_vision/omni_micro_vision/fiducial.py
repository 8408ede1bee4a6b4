"""The fiducial printed on the robot's top: what the renderer draws and the tracker looks for.

Two white dots on the robot's X axis, the front one larger so that the heading has a sign: a
4 mm pair for the macro camera and, at the centre, a 0.6 mm pair the micro camera sees whole.

**Who is who.** On a platform shared by several robots (a fleet), robot k also carries
its code: two small dots in five slots beside each pair, in the slots ``ROBOT_CODES[k]`` names
(ten robots). Every code has exactly two dots, so a dot lost (blur, dirt) or added (a
reflection) gives a word that is nobody's: the tracker then says it cannot tell the robot, and
never reads one robot as another by a single dot. A single robot carries no code.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from itertools import combinations

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


# The code slots, in the robot frame, beside each pair: two rows across the robot's X axis,
# clear of the window the tracker weighs a pair's dot in (the macro pair's: 2.7 mm from its
# dots' centres at least; 0.8 mm inside the chassis's edge), so that a code never pulls a
# dot's centroid (at 2.2 mm they did, by up to 13 um); the micro slots 0.19 mm from its dots.
MACRO_CODE_SLOTS = (Dot(-1.6e-3, 3.0e-3, 0.3e-3), Dot(0.0, 3.0e-3, 0.3e-3),
                    Dot(1.6e-3, 3.0e-3, 0.3e-3), Dot(-0.8e-3, -3.0e-3, 0.3e-3),
                    Dot(0.8e-3, -3.0e-3, 0.3e-3))
MICRO_CODE_SLOTS = (Dot(-0.2e-3, 0.25e-3, 0.02e-3), Dot(0.0, 0.25e-3, 0.02e-3),
                    Dot(0.2e-3, 0.25e-3, 0.02e-3), Dot(-0.1e-3, -0.25e-3, 0.02e-3),
                    Dot(0.1e-3, -0.25e-3, 0.02e-3))
# Robot k's slots: every pair of the five, in order (ten robots, FLEET_COLOURS' ten).
ROBOT_CODES: tuple[tuple[int, int], ...] = tuple(combinations(range(5), 2))


def code_slots_for(camera: CameraModel) -> tuple[Dot, ...]:
    """The slots of the pair ``camera`` tracks (``fiducial_for``)."""
    return MACRO_CODE_SLOTS if fiducial_for(camera) is MACRO_FIDUCIAL else MICRO_CODE_SLOTS


def code_dots(robot: int | None) -> tuple[Dot, ...]:
    """The code dots robot ``robot`` carries beside both pairs (none for a single robot).

    Raises
    ------
    ValueError
        If there is no code for ``robot``.
    """
    if robot is None:
        return ()
    if not 0 <= robot < len(ROBOT_CODES):
        raise ValueError(f'robot {robot}: fiducial codes are printed for robots 0 to '
                         f'{len(ROBOT_CODES) - 1}')
    return tuple(slots[slot] for slots in (MACRO_CODE_SLOTS, MICRO_CODE_SLOTS)
                 for slot in ROBOT_CODES[robot])


def robot_of_code(lit: tuple[bool, ...]) -> int | None:
    """The robot whose code is the slots ``lit`` (None: nobody's, a dot lost or added)."""
    word = tuple(slot for slot, on in enumerate(lit) if on)
    return ROBOT_CODES.index(word) if word in ROBOT_CODES else None
