"""A capture as the controllers see it, several captures of a still robot made one, and the
captures that came before the goal they belong to."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

from omni_micro_common.clocks import clock_mismatch
from omni_micro_common.conventions import CaptureUncertainty


@dataclass(frozen=True)
class Observation:
    """A capture as the controller sees it (any camera that follows the contract)."""

    stamp_s: float
    x_m: float
    y_m: float
    phi_rad: float
    camera: str = ''
    # None: unknown, taken as exact (unit tests); the nodes and the twin always give one.
    uncertainty: CaptureUncertainty | None = None
    count: int = 1                        # captures averaged into this one

    @property
    def radius_95_m(self) -> float:
        return 0.0 if self.uncertainty is None else self.uncertainty.radius_95_m


@dataclass(frozen=True)
class Refused:
    """A capture a controller cannot use: the line that says why, and whether it is on another
    clock than the robot's (which ends a goal) rather than merely unreadable (which is skipped)."""

    line: str
    foreign_clock: bool = False


def read_capture(camera: str, frame_id: str, expected_frame_id: str, stamp_s: float,
                 pose: tuple[float, float, float], uncertainty: CaptureUncertainty,
                 robot_time_s: float) -> Observation | Refused:
    """A capture (x, y, heading) as a controller reads it, or why it cannot, the robot's clock
    reading ``robot_time_s``."""
    if frame_id != expected_frame_id:
        return Refused(f'ignored {camera} capture in frame {frame_id!r}: expected '
                       f'{expected_frame_id!r}')
    seen = Observation(stamp_s, *pose, camera, uncertainty)
    if not all(math.isfinite(v) for v in pose):
        return Refused(f'ignored {camera} capture with a non-finite pose: {seen}')
    mismatch = clock_mismatch(f'a {camera} capture', stamp_s, 'the robot', robot_time_s)
    if mismatch is not None:
        return Refused(mismatch, foreign_clock=True)
    return seen


def mean_observation(observations: list[Observation]) -> Observation:
    """One observation of a still robot from several captures of the same camera: the mean
    position, the circular mean heading, the last stamp, and the mean's (smaller) spread."""
    if len(observations) == 1:
        return observations[0]
    count = len(observations)
    heading = math.atan2(sum(math.sin(o.phi_rad) for o in observations),
                         sum(math.cos(o.phi_rad) for o in observations))
    last = observations[-1]
    return Observation(last.stamp_s, math.fsum(o.x_m for o in observations) / count,
                       math.fsum(o.y_m for o in observations) / count, heading, last.camera,
                       None if last.uncertainty is None else last.uncertainty.averaged(count),
                       count)


class CapturesBeforeTheGoal:
    """Stationary captures that came while no goal ran, for the goal stamped at or before them
    that arrives after them: a fleet's coordinator hands a goal out stamped with the end it
    follows, and time runs up to ``lockstep_max_lead_s`` past that end before the goal is taken.
    A controller takes them as if they had come after the goal, as the twin feeds them.
    ``kept``: the most a lead of 40 ms holds at 120 Hz from two cameras, twice over."""

    def __init__(self, kept: int = 20) -> None:
        self._held: deque[Observation] = deque(maxlen=kept)

    def keep(self, seen: Observation) -> None:
        self._held.append(seen)

    def since(self, stamp_s: float) -> list[Observation]:
        """Those stamped at or after ``stamp_s``, in the order they came; the rest forgotten."""
        held = [seen for seen in self._held if seen.stamp_s >= stamp_s]
        self._held.clear()
        return held
