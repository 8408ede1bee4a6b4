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

from collections.abc import Sequence
from dataclasses import dataclass

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


@dataclass(frozen=True)
class RobotCapture:
    """One robot's capture: the robot's code, the camera and frame stamp, the pose."""

    robot: int
    camera: str
    stamp_ns: int
    pose: tuple[float, float, float]


class FleetCaptures:
    """Captures per robot from the frames of ``cameras`` (their names, finest first).

    ``still_tolerance_m``: per camera, how close a robot's last ``still_frames`` poses agree
    when it is still.
    """

    def __init__(self, cameras: Sequence[str], robots: Sequence[int], still_frames: int,
                 still_tolerance_m: dict[str, float]) -> None:
        self.robots = list(robots)
        self._stillness = {(camera, robot): StillnessRule(still_frames,
                                                          still_tolerance_m[camera])
                           for camera in cameras for robot in self.robots}
        self._arbiters: dict[int, CameraArbiter[RobotCapture]] = {
            robot: CameraArbiter(cameras) for robot in self.robots}

    def on_frame(self, camera: str, stamp_ns: int, sightings: Sequence[Sighting]) -> tuple[
            list[RobotCapture], list[Sighting]]:
        """One frame of ``camera``: the captures now due (every robot's, in stamp order) and the
        sightings no capture came from because nobody of this run is named in them."""
        named = {s.robot: s for s in sightings if s.robot in self._arbiters}
        unnamed = [s if s.robot is None else Sighting(
                       s.pose, None, f'{robot_name(s.robot)} is not one of this run\'s robots')
                   for s in sightings if s.robot not in self._arbiters]
        due: list[tuple[int, RobotCapture]] = []
        for robot in self.robots:
            sighting = named.get(robot)
            rule = self._stillness[camera, robot]
            capture = None
            if sighting is None:
                rule.reset()
            elif rule.still(*sighting.pose[:2]):
                capture = RobotCapture(robot, camera, stamp_ns, sighting.pose)
            due += self._arbiters[robot].on_frame(camera, stamp_ns, sighting is not None,
                                                  capture)
        return [capture for _, capture in sorted(due, key=lambda item: item[0])], unnamed
