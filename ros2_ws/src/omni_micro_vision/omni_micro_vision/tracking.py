"""The fiducial tracker: a pose per frame, and from poses to captures (when the robot counts
as still, and which camera speaks).

No rclpy: ``tracker_node`` (and ``omni-micro track``, offline) are thin adapters of these.

**The tracker.** Threshold halfway between the surround and the brightest dots, outer
contours, the two dots picked by their expected areas, each located by its intensity-weighted
centroid (sub-pixel), and the pose from their midpoint and direction; first near the last pose
when it is known. A frame where the pair is not found, is cut by the image's edge or is
ambiguous gives no pose and says why.

**Frame after frame.** Each frame is searched first around the pose the last one gave, then
whole: the same frames give the same poses whoever reads them, live or from a bag.

**Still.** A camera's pose is a capture only once its last ``frames`` frames agree within
``tolerance_px`` of its pixel, decided from the images alone (never from odometry).

**One camera at a time.** Where the fields overlap, both cameras could capture the same stop,
and the controller takes the first capture that arrives: which one would then depend on message
timing. As ``vision_node`` does (the micro camera whenever it sees the robot), a coarser
camera's capture is held until every finer camera has a frame stamped at or after it, and is
dropped if that frame shows the fiducial. The decision depends on stamps only, so two cameras
with different frame clocks (real ones) are arbitrated the same way as simulated ones.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

import numpy as np

from omni_micro_vision.encodings import full_scale
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fiducial import DOT_LEVEL, PLATFORM_LEVEL, Fiducial, fiducial_for
from omni_micro_vision.geometry import PlaneMap


@dataclass(frozen=True)
class Track:
    """The tracker's answer for one frame: a pose (x, y, heading in the platform frame), or
    why there is none."""

    pose: tuple[float, float, float] | None = None
    reason: str = ''

    @property
    def found(self) -> bool:
        return self.pose is not None


# Where the last pose is known, the fiducial is first looked for around it, a quarter of the
# pair's baseline beyond the pair (1 mm for the macro pair: a robot at 14 mm/s goes 0.47 mm
# between frames at 30 Hz; a faster one is found in the whole frame).
SEARCH_MARGIN_BASELINES = 0.25


def track(image: np.ndarray, plane: PlaneMap, near: tuple[float, float] | None = None,
          full_scale: int | None = None) -> Track:
    """The robot's pose (platform frame) in ``image``, a frame of the camera whose pixels
    ``plane`` maps to the platform, from its fiducial.

    ``near``: where the robot was in the last frame (platform x, y). The fiducial is then first
    looked for in a window around it, and in the whole frame only if it is not found there
    whole (a quarter of the micro camera's frame, 67 x 54 of the macro camera's 1280 x 1024
    pixels: most of the tracker's time per frame was the whole frame's histogram).
    ``full_scale``: the largest count the sensor gives (:func:`encodings.full_scale`); by
    default the image type's.

    Raises
    ------
    CameraConfigError
        If ``image`` is not a 2-D array of the map's resolution (a corrupt frame).
    """
    columns, rows = check_frame(image, plane)
    scale = int(np.iinfo(image.dtype).max) if full_scale is None else full_scale
    pixel_m = plane.pixel_size_m
    fiducial = fiducial_for(plane.field_camera)
    if near is not None:
        column, row = plane.to_pixels(np.array([near]))[0]
        reach = ((0.5 + SEARCH_MARGIN_BASELINES) * fiducial.baseline_m
                 + fiducial.front.radius_m)
        reach_u, reach_v = (reach * extent for extent in plane.pixels_per_metre)
        if math.isfinite(column) and math.isfinite(row):
            region = (max(0, int(row - reach_v)), min(rows, int(row + reach_v) + 1),
                      max(0, int(column - reach_u)), min(columns, int(column + reach_u) + 1))
            if region[1] - region[0] > 8 and region[3] - region[2] > 8:
                found = _locate(image, plane, pixel_m, fiducial, region, scale)
                if found.found:
                    return found
    return _locate(image, plane, pixel_m, fiducial, (0, rows, 0, columns), scale)


def check_frame(image: np.ndarray, plane: PlaneMap) -> tuple[int, int]:
    """The frame's columns and rows, once ``image`` is a 2-D array of the map's resolution.

    Raises
    ------
    CameraConfigError
        If it is not (a corrupt frame).
    """
    columns, rows = plane.resolution_px
    if image.ndim != 2 or image.shape != (rows, columns):
        raise CameraConfigError(f'{plane.name}: expected a {columns} x {rows} mono image, got '
                                f'shape {image.shape}')
    return columns, rows


def _locate(image: np.ndarray, plane: PlaneMap, pixel_m: tuple[float, float],
            fiducial: Fiducial, region: tuple[int, int, int, int], full_scale: int) -> Track:
    """The fiducial in ``region`` (first row, end row, first column, end column) of ``image``;
    a blob touching the region's border is cut (by the field's edge when the region is the
    whole frame)."""
    import cv2

    r0, r1, c0, c1 = region
    part = image[r0:r1, c0:c1]
    px, py = pixel_m
    levels = bright_blobs(part, full_scale)
    if levels is None:
        return Track(reason='no fiducial: nothing brighter than the platform')
    binary, part_boxes, _ = levels
    # In frame pixels: the region's offset added.
    boxes = [(left + c0, top + r0, width, height) for left, top, width, height in part_boxes]
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
        return Track(reason=f'fiducial cut by the edge of the {plane.name} field')
    if missing:
        sizes = ', '.join(f'{expected[name]:.0f} px' for name in missing)
        return Track(reason=f'fiducial not found: no {" or ".join(missing)} dot of the '
                            f'expected size ({sizes})')
    if len(found['front']) > 1 or len(found['back']) > 1:
        return Track(reason=f'ambiguous: {len(found["front"])} front and {len(found["back"])} '
                            'back dot candidates')
    centres: dict[str, tuple[float, float]] = {}
    for name in ('front', 'back'):
        centre = dot_centre(image, boxes[found[name][0]])
        if centre is None:
            return Track(reason=f'{name} dot has no contrast')
        centres[name] = centre[:2]
    # Each dot's centre through the lens and onto the platform: the heading is read there, so
    # a turned or mirrored image gives the platform's heading.
    front, back = plane.to_platform(np.array([centres['front'], centres['back']]))
    return Track(pair_pose(fiducial, front, back))


def bright_blobs(part: np.ndarray, full_scale: int) -> tuple[
        np.ndarray, list[tuple[int, int, int, int]], tuple[float, float]] | None:
    """What stands out of the platform in ``part``: the pixels above the threshold, each
    blob's bounding box (left, top, width, height) and the levels (surround, peak) the
    threshold lies halfway between; None when nothing is brighter than the platform."""
    import cv2

    # The surround as the median level, the peak as the tenth brightest pixel: both from the
    # histogram (one pass over the frame, no sort or float copy of a megapixel).
    histogram = cv2.calcHist([part], [0], None, [full_scale + 1], [0, full_scale + 1]).ravel()
    cumulative = np.cumsum(histogram)
    background = float(np.searchsorted(cumulative, 0.5 * cumulative[-1]))
    peak = float(np.searchsorted(cumulative, cumulative[-1] - 10))
    if peak - background < 0.2 * full_scale * (DOT_LEVEL - PLATFORM_LEVEL):
        return None
    threshold = 0.5 * (background + peak)
    binary = np.asarray(cv2.compare(part, np.array([threshold]), cv2.CMP_GT))
    # Blobs as outer contours (a few on a megapixel: far cheaper than labelling every pixel);
    # a blob's area is its pixels above the threshold inside its bounding box.
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
    boxes = [(left, top, width, height) for left, top, width, height in
             (cv2.boundingRect(contour) for contour in contours)]
    return binary, boxes, (background, peak)


def dot_centre(image: np.ndarray, box: tuple[int, int, int, int]) -> tuple[
        float, float, float] | None:
    """The intensity-weighted centroid (column, row) of the dot in ``box`` above its local
    surround (the chassis around it), and that surround's level; None without contrast."""
    rows, columns = image.shape
    left, top, width, height = box
    pad = max(2, round(1.5 * min(width, height) / 4) + 2)
    y0, y1 = max(0, top - pad), min(rows, top + height + pad)
    x0, x1 = max(0, left - pad), min(columns, left + width + pad)
    window = image[y0:y1, x0:x1].astype(np.float32)
    surround = float(np.median(np.concatenate([window[0], window[-1], window[:, 0],
                                               window[:, -1]])))
    weights = np.clip(window - surround, 0.0, None)
    total = float(weights.sum())
    if total <= 0.0:
        return None
    rows_index, columns_index = np.mgrid[y0:y1, x0:x1]
    return (float((weights * columns_index).sum() / total),
            float((weights * rows_index).sum() / total), surround)


def pair_pose(fiducial: Fiducial, front: Sequence[float],
              back: Sequence[float]) -> tuple[float, float, float]:
    """The robot's pose from its pair's dot centres on the platform."""
    (fx, fy), (bx, by) = front, back
    # The dots sit symmetrically about the centre on the robot's X axis.
    offset = 0.5 * (fiducial.front.x_m + fiducial.back.x_m)
    heading = math.atan2(fy - by, fx - bx)
    return (float(0.5 * (fx + bx) - offset * math.cos(heading)),
            float(0.5 * (fy + by) - offset * math.sin(heading)), heading)


T = TypeVar('T')


class FrameTracker:
    """:func:`track` on the frames of one camera, in order.

    ``bit_depth``: the sensor's (0: the least that holds every frame seen so far, so that a
    12-bit sensor's counts in mono16 are read on their own scale).
    """

    def __init__(self, plane: PlaneMap, bit_depth: int = 0) -> None:
        self.plane = plane
        self.bit_depth = bit_depth
        self._full_scale = 0
        self._last: tuple[float, float] | None = None

    def reset(self) -> None:
        self._last = None

    def __call__(self, image: np.ndarray) -> Track:
        self._full_scale = max(self._full_scale, full_scale(image, self.bit_depth))
        result = track(image, self.plane, near=self._last, full_scale=self._full_scale)
        self._last = None if result.pose is None else result.pose[:2]
        return result


@dataclass
class StillnessRule:
    """The last ``frames`` poses (x, y in metres) agree within ``tolerance_m``."""

    frames: int
    tolerance_m: float

    def __post_init__(self) -> None:
        self._recent: deque[tuple[float, float]] = deque(maxlen=self.frames)

    def reset(self) -> None:
        self._recent.clear()

    def still(self, x_m: float, y_m: float) -> bool:
        """Add one frame's pose; whether the robot is still as of this frame."""
        self._recent.append((x_m, y_m))
        return len(self._recent) == self.frames and all(
            math.hypot(x - x_m, y - y_m) <= self.tolerance_m for x, y in self._recent)


class CameraArbiter(Generic[T]):
    """Lets a capture through unless a finer camera saw the robot at the same time.

    Parameters
    ----------
    finest_first : the cameras' names, the finest (smallest pixel) first.
    """

    KEPT_FRAMES = 64

    def __init__(self, finest_first: Sequence[str]) -> None:
        self.order = list(finest_first)
        self._seen: dict[str, deque[tuple[int, bool]]] = {
            name: deque(maxlen=self.KEPT_FRAMES) for name in self.order}
        self._held: list[tuple[int, str, T]] = []

    def on_frame(self, camera: str, stamp_ns: int, found: bool,
                 capture: T | None) -> list[tuple[int, T]]:
        """One frame of ``camera``: whether its fiducial was found, and its capture if the robot
        is still. Returns the captures now due, (stamp, capture) in stamp order."""
        self._seen[camera].append((stamp_ns, found))
        if capture is not None:
            self._held.append((stamp_ns, camera, capture))
        due, waiting = [], []
        for stamp, name, held in self._held:
            verdict = self._finer_saw_robot(name, stamp)
            if verdict is None:
                waiting.append((stamp, name, held))
            elif not verdict:
                due.append((stamp, held))
        self._held = waiting
        return sorted(due, key=lambda item: item[0])

    def _finer_saw_robot(self, camera: str, stamp_ns: int) -> bool | None:
        """Whether a finer camera's first frame at or after ``stamp_ns`` shows the robot (None:
        some finer camera has no such frame yet)."""
        for finer in self.order[:self.order.index(camera)]:
            later = [found for stamp, found in self._seen[finer] if stamp >= stamp_ns]
            if not later:
                return None
            if later[0]:
                return True
        return False
