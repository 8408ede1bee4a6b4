"""Captures of several robots under one camera pair: each frame's sightings
(:mod:`omni_micro_vision.code_reading`) turned into each named robot's captures as
:mod:`omni_micro_vision.tracking` turns one robot's poses into its captures. No rclpy:
``tracker_node`` with ``robots`` is the adapter.

Per robot, as for one: a capture once its last frames agree (its own stillness rule per
camera), and only from the finest camera that sees it (its own arbiter: the micro camera seeing
robot 2 silences the macro camera's captures of robot 2, not of robot 0). A robot is seen in a
frame only where the frame names it: a sighting that cannot be named, or names a robot that is
not in the run, gives nobody a capture and is handed back to be reported.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Generic, TypeVar

from omni_micro_common.topic_names import robot_index, robot_name
from omni_micro_vision.code_reading import Sighting
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.fiducial import ROBOT_CODES
from omni_micro_vision.tracking import CameraArbiter, StillnessRule


def robot_codes(names: Sequence[str]) -> dict[str, int]:
    """Each fleet robot's code, from its namespace (``robot_k`` carries code k).

    Raises
    ------
    CameraConfigError
        A name that is not robot_k with a printed code, or one named twice.
    """
    codes: dict[str, int] = {}
    for name in names:
        code = robot_index(name)
        if code is None or code >= len(ROBOT_CODES) or name in codes:
            raise CameraConfigError(
                f'robots: {name!r} is not a robot with a code of its own ({robot_name(0)} to '
                f'{robot_name(len(ROBOT_CODES) - 1)}, each once: the codes printed on them)')
        codes[name] = code
    return codes


Pose = tuple[float, float, float]
M = TypeVar('M')
# A moving robot's capture as the caller makes it: (camera, frame stamp in ns, the pose, the
# same camera's last sighting of the robot as (stamp in ns, x, y)) -> its capture in motion, or
# None when the robot moves too fast for one.
InMotion = Callable[[str, int, Pose, tuple[int, float, float]], 'M | None']


@dataclass(frozen=True)
class RobotCapture:
    """One robot's capture: the robot's code, the camera and frame stamp, the pose."""

    robot: int
    camera: str
    stamp_ns: int
    pose: Pose


@dataclass(frozen=True)
class FleetFrame(Generic[M]):
    """What one frame gave: the captures now due and the captures in motion now due (each
    robot's, in stamp order, the latter as (robot, capture)), and the sightings nobody of the
    run is named in."""

    captures: list[RobotCapture]
    in_motion: list[tuple[int, M]]
    unnamed: list[Sighting]


class FleetCaptures(Generic[M]):
    """Captures per robot from the frames of ``cameras`` (their names, finest first).

    ``still_tolerance_m``: per camera, how close a robot's last ``still_frames`` poses agree
    when it is still. ``in_motion``: how a moving robot's frame becomes its capture in motion
    (none without it).
    """

    def __init__(self, cameras: Sequence[str], robots: Sequence[int], still_frames: int,
                 still_tolerance_m: dict[str, float],
                 in_motion: InMotion[M] | None = None) -> None:
        self.robots = list(robots)
        self._stillness = {(camera, robot): StillnessRule(still_frames,
                                                          still_tolerance_m[camera])
                           for camera in cameras for robot in self.robots}
        self._arbiters: dict[int, CameraArbiter[RobotCapture]] = {
            robot: CameraArbiter(cameras) for robot in self.robots}
        self._in_motion = in_motion
        self._motion_arbiters: dict[int, CameraArbiter[M]] = {
            robot: CameraArbiter(cameras) for robot in self.robots}
        self._last_seen: dict[tuple[str, int], tuple[int, float, float]] = {}

    def on_frame(self, camera: str, stamp_ns: int,
                 sightings: Sequence[Sighting]) -> FleetFrame[M]:
        """One frame of ``camera``: what it gives (:class:`FleetFrame`)."""
        named = {s.robot: s for s in sightings if s.robot in self._arbiters}
        unnamed = [s if s.robot is None else Sighting(
                       s.pose, None, f'{robot_name(s.robot)} is not one of this run\'s robots')
                   for s in sightings if s.robot not in self._arbiters]
        due: list[tuple[int, RobotCapture]] = []
        moving: list[tuple[int, int, M]] = []
        for robot in self.robots:
            sighting = named.get(robot)
            rule = self._stillness[camera, robot]
            capture, in_motion = None, None
            if sighting is None:
                rule.reset()
                self._last_seen.pop((camera, robot), None)
            else:
                x, y, _ = sighting.pose
                last = self._last_seen.get((camera, robot))
                self._last_seen[camera, robot] = (stamp_ns, x, y)
                if rule.still(x, y):
                    capture = RobotCapture(robot, camera, stamp_ns, sighting.pose)
                elif self._in_motion is not None and last is not None:
                    in_motion = self._in_motion(camera, stamp_ns, sighting.pose, last)
            due += self._arbiters[robot].on_frame(camera, stamp_ns, sighting is not None,
                                                  capture)
            if self._in_motion is not None:
                # A finer camera that found the robot but lost it to the blur leaves it to the
                # coarser.
                moving += [(stamp, robot, held) for stamp, held in self._motion_arbiters[
                    robot].on_frame(camera, stamp_ns, in_motion is not None, in_motion)]
        moving.sort(key=lambda item: item[0])
        return FleetFrame([capture for _, capture in sorted(due, key=lambda item: item[0])],
                          [(robot, held) for _, robot, held in moving], unnamed)
