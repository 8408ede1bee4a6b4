"""Who is who in a frame of a platform shared by several robots: every robot's fiducial found,
each named by the code printed beside its pair (``fiducial.ROBOT_CODES``), and any robot the
frame cannot name said so. No rclpy.

The pairs are found as :func:`tracking.track` finds one (the same threshold, blobs and
centroids), then paired by their baseline: two robots never overlap (9 mm discs), so a front
dot lies a baseline from its own back dot and at least a chassis diameter less a baseline
(5 mm of the macro pair's 4) from any other. Each pair's code slots are then read where its pose
puts them. A robot is named only when its pair is unambiguous, its code is a robot's code and
no other robot in the frame reads as the same one: otherwise the sighting has no robot and says
why, and a caller never takes one robot's capture for another's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_common.topic_names import robot_name
from omni_micro_vision.encodings import full_scale as scale_of
from omni_micro_vision.fiducial import code_slots_for, fiducial_for, robot_of_code
from omni_micro_vision.geometry import PlaneMap
from omni_micro_vision.tracking import bright_blobs, check_frame, dot_centre, pair_pose

# A front and a back dot are one robot's when their distance is its baseline within this share
# (another robot's dot is at least 25 % of a baseline further).
PAIRING_SHARE = 0.15


@dataclass(frozen=True)
class Sighting:
    """A robot in a frame: its pose (platform frame), whose code it carries (None: it cannot be
    told, ``reason`` says why)."""

    pose: tuple[float, float, float]
    robot: int | None
    reason: str = ''


@dataclass(frozen=True)
class _Dot:
    surround: float
    platform: tuple[float, float]


def identify(image: np.ndarray, plane: PlaneMap, full_scale: int | None = None) -> tuple[
        list[Sighting], str]:
    """Every robot whose pair ``image`` holds whole, each named by its code if it can be, and
    why there is none when none is found ('' when some are).

    Raises
    ------
    CameraConfigError
        If ``image`` is not a 2-D array of the map's resolution (a corrupt frame).
    """
    import cv2

    columns, rows = check_frame(image, plane)
    scale = scale_of(image, 0) if full_scale is None else full_scale
    blobs = bright_blobs(image, scale)
    if blobs is None:
        return [], 'no fiducial: nothing brighter than the platform'
    binary, boxes, (_, peak) = blobs
    fiducial = fiducial_for(plane.field_camera)
    px, py = plane.pixel_size_m
    expected = {name: math.pi * dot.radius_m ** 2 / (px * py)
                for name, dot in (('front', fiducial.front), ('back', fiducial.back))}
    dots: dict[str, list[_Dot]] = {'front': [], 'back': []}
    for left, top, width, height in boxes:
        if left == 0 or top == 0 or left + width >= columns or top + height >= rows:
            continue    # cut by the field's edge: part of a robot no capture may come from
        area = cv2.countNonZero(binary[top:top + height, left:left + width])
        for name, size in expected.items():
            if 0.5 * size <= area <= 1.6 * size:
                centre = dot_centre(image, (left, top, width, height))
                if centre is not None:
                    column, row, surround = centre
                    platform = plane.to_platform(np.array([[column, row]]))[0]
                    dots[name].append(_Dot(surround, (float(platform[0]),
                                                      float(platform[1]))))
    if not dots['front'] and not dots['back']:
        return [], 'fiducial not found: no dot of the expected sizes'
    baseline = fiducial.baseline_m
    partners = {index: [other for other, back in enumerate(dots['back'])
                        if abs(math.dist(front.platform, back.platform) - baseline)
                        <= PAIRING_SHARE * baseline]
                for index, front in enumerate(dots['front'])}
    claims = [sum(back in found for found in partners.values())
              for back in range(len(dots['back']))]
    sightings = []
    for index, found in partners.items():
        front = dots['front'][index]
        if not found:
            continue    # a lone front dot: no pose to give (cut, or a reflection)
        back = dots['back'][found[0]]
        pose = pair_pose(fiducial, front.platform, back.platform)
        if len(found) > 1 or claims[found[0]] > 1:
            sightings.append(Sighting(pose, None, 'cannot tell apart: its pair is ambiguous '
                                      '(another robot too close)'))
            continue
        lit = _read_code(image, plane, pose, front.surround, peak)
        if lit is None:
            sightings.append(Sighting(pose, None, 'cannot tell apart: its code is cut by the '
                                      f'edge of the {plane.name} field'))
            continue
        robot = robot_of_code(lit)
        sightings.append(Sighting(pose, robot, '' if robot is not None else
                                  'cannot tell apart: its code '
                                  f'{"".join("1" if on else "0" for on in lit)} is no robot\'s'))
    return _unique(sightings), '' if sightings else 'fiducial not found: no pair whole'


def _read_code(image: np.ndarray, plane: PlaneMap, pose: tuple[float, float, float],
               chassis: float, peak: float) -> tuple[bool, ...] | None:
    """Which of the code slots are printed, read at the pixels the pose puts them on: lit when
    the brightest pixel within half a dot of the slot's centre is above halfway from the chassis
    to the dots (None: a slot is outside the frame)."""
    x, y, phi = pose
    slots = code_slots_for(plane.field_camera)
    centres = plane.to_pixels(np.array([
        (x + math.cos(phi) * slot.x_m - math.sin(phi) * slot.y_m,
         y + math.sin(phi) * slot.x_m + math.cos(phi) * slot.y_m) for slot in slots]))
    rows, columns = image.shape
    threshold = 0.5 * (chassis + peak)
    lit = []
    for slot, (column, row) in zip(slots, centres, strict=True):
        reach = max(1, round(0.5 * slot.radius_m / min(plane.pixel_size_m)))
        if not (math.isfinite(column) and math.isfinite(row)):
            return None
        c, r = round(column), round(row)
        if not (reach <= c < columns - reach and reach <= r < rows - reach):
            return None
        lit.append(float(image[r - reach:r + reach + 1, c - reach:c + reach + 1].max())
                   > threshold)
    return tuple(lit)


def _unique(sightings: list[Sighting]) -> list[Sighting]:
    """Two robots read as one code: neither is named (one of them is not who it reads as)."""
    named = [sighting.robot for sighting in sightings if sighting.robot is not None]
    return [Sighting(s.pose, None, f'cannot tell apart: two robots read as {robot_name(s.robot)}')
            if s.robot is not None and named.count(s.robot) > 1 else s for s in sightings]
