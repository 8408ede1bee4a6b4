"""The tracker on recorded frames, offline, as tracker_node would run it (``omni-micro track``):
one robot's fiducial frame by frame (found or why not, still or moving), several robots' codes
(who is named in each frame, and why a robot could not be), and the noise a camera shows over
its still frames, as its params should state it. No rclpy: the frames come as deserialized
sensor_msgs/Image messages with their stamps."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_common.topic_names import robot_name
from omni_micro_vision.code_reading import identify
from omni_micro_vision.encodings import full_scale
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.image_messages import image_array
from omni_micro_vision.tracked_camera import TrackedCamera
from omni_micro_vision.tracking import FrameTracker, StillnessRule

# One row per frame: stamp, found, still, x, y, heading, reason.
FrameRow = tuple[float, bool, bool, float, float, float, str]
# One row per robot seen in a frame: stamp, robot ('' when not named), still, x, y, heading,
# reason.
RobotRow = tuple[float, str, bool, float, float, float, str]


def track_frames(frames: Iterable[tuple[float, Any]], camera: TrackedCamera, still_frames: int,
                 tolerance_px: float) -> list[FrameRow]:
    """One robot's fiducial in each (stamp, image message) of ``frames``, as tracker_node finds
    it and decides that the robot is still."""
    stillness = StillnessRule(still_frames, tolerance_px * min(camera.plane.pixel_size_m))
    tracker = FrameTracker(camera.plane, camera.bit_depth)
    rows: list[FrameRow] = []
    for stamp, msg in frames:
        try:
            pixels = image_array(msg, camera.plane.resolution_px)
            found = tracker(pixels)
        except CameraConfigError as error:
            stillness.reset()
            tracker.reset()
            rows.append((stamp, False, False, math.nan, math.nan, math.nan,
                         f'refused: {error}'))
            continue
        if found.pose is None:
            stillness.reset()
            rows.append((stamp, False, False, math.nan, math.nan, math.nan, found.reason))
        else:
            x, y, heading = found.pose
            rows.append((stamp, True, stillness.still(x, y), x, y, heading, ''))
    return rows


@dataclass
class NamedRobots:
    """Who was named in a run of frames: ``rows`` a robot seen per frame, ``refused`` why a
    frame showed no robot at all, by reason."""

    frames: int
    rows: list[RobotRow]
    refused: Counter[str]


def name_robots(frames: Iterable[tuple[float, Any]], camera: TrackedCamera,
                codes: dict[str, int], still_frames: int, tolerance_px: float) -> NamedRobots:
    """Each robot of ``codes`` (name -> fiducial code) in each (stamp, image message), as
    tracker_node names it and decides that it is still; a robot seen but not named, with why."""
    names = {code: name for name, code in codes.items()}
    tolerance_m = tolerance_px * min(camera.plane.pixel_size_m)
    stillness = {code: StillnessRule(still_frames, tolerance_m) for code in names}
    named = NamedRobots(0, [], Counter())
    scale = 0
    for stamp, msg in frames:
        named.frames += 1
        try:
            pixels = image_array(msg, camera.plane.resolution_px)
            scale = max(scale, full_scale(pixels, camera.bit_depth))
            sightings, reason = identify(pixels, camera.plane, scale)
        except CameraConfigError as error:
            sightings, reason = [], f'refused: {error}'
        if not sightings:
            named.refused[reason] += 1
        seen = set()
        for sighting in sightings:
            x, y, heading = sighting.pose
            if sighting.robot in names:
                seen.add(sighting.robot)
                still = stillness[sighting.robot].still(x, y)
                named.rows.append((stamp, names[sighting.robot], still, x, y, heading, ''))
            else:
                why = sighting.reason or (f'{robot_name(sighting.robot)} is not one of --robots'
                                          if sighting.robot is not None else 'not named')
                named.rows.append((stamp, '', False, x, y, heading, why))
        for code in set(names) - seen:
            stillness[code].reset()
    return named


@dataclass(frozen=True)
class StillSpread:
    """How a camera's poses scatter over its still frames (``spread_m_rad``: x, y in m, heading
    in rad), what its params state now, and the ``noise_px`` and ``quantisation_px`` that would
    state what it does."""

    spread_m_rad: np.ndarray
    stated: CaptureUncertainty
    noise_px: float
    quantisation_px: float


def still_spread(rows: list[FrameRow], camera: TrackedCamera) -> StillSpread | None:
    """The spread over ``rows``' still frames; None when no two of them come in a row (a
    single still frame between moves scatters about nothing)."""
    still = [index for index, row in enumerate(rows) if row[2]]
    poses = np.array([rows[index][3:6] for index in still]).reshape(-1, 3)
    # Scatter about each still stretch's own mean: a robot moved between stretches does
    # not count as noise.
    breaks = np.flatnonzero(np.diff(still) > 1) + 1
    stretches = [part - part.mean(axis=0) for part in np.split(poses, breaks) if len(part) >= 2]
    if not stretches:
        return None
    spread = np.concatenate(stretches).std(axis=0)
    stated = camera.uncertainty(float(np.median(poses[:, 2])))
    # The stated position spread is mark_sigma / sqrt(2) pixels, mark_sigma^2 = noise^2 +
    # quantisation^2 / 12: solve for noise, or for both when the grid alone says too much.
    pixel = float(np.mean(camera.plane.pixel_size_m))
    mark_sigma = math.sqrt(2.0) * float(np.mean(spread[:2])) / pixel
    quantisation = camera.quantisation_px
    if mark_sigma ** 2 < quantisation ** 2 / 12.0:
        quantisation = 0.0
    noise = math.sqrt(mark_sigma ** 2 - quantisation ** 2 / 12.0)
    return StillSpread(spread, stated, noise, quantisation)
