"""From per-frame poses to captures: when the robot counts as still, and which camera speaks.

No rclpy: ``tracker_node`` (and ``omni-micro track``, offline) feed these with what
:class:`FrameTracker` finds.

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

from omni_micro_vision.camera import CameraModel
from omni_micro_vision.rendering import Track, track

T = TypeVar('T')


class FrameTracker:
    """:func:`omni_micro_vision.rendering.track` on the frames of one camera (turned by
    ``yaw_rad`` about its centre), in order."""

    def __init__(self, yaw_rad: float = 0.0) -> None:
        self.yaw_rad = yaw_rad
        self._last: tuple[float, float] | None = None

    def reset(self) -> None:
        self._last = None

    def __call__(self, image: np.ndarray, camera: CameraModel) -> Track:
        result = track(image, camera, near=self._last, yaw_rad=self.yaw_rad)
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
