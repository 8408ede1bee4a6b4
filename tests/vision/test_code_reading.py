"""Who is who in a rendered frame of several robots (omni_micro_vision.code_reading): each
robot named by the code printed on it, wherever it stands and as it moves, and a robot the
frame cannot name reported, never taken for another."""

from __future__ import annotations

import math

import numpy as np
import pytest

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.code_reading import identify
from omni_micro_vision.fiducial import ROBOT_CODES, code_dots, robot_of_code
from omni_micro_vision.geometry import PlaneMap
from omni_micro_vision.rendering import InView, Sensor, render, render_robots
from omni_micro_vision.tracking import track

MACRO = DEFAULT_RIG.macro
MICRO = DEFAULT_RIG.micro


def frame(camera, robots, seed=0):
    return render_robots(camera, Sensor(), robots, np.random.default_rng([7, seed]))


def by_robot(sightings):
    return {sighting.robot: sighting for sighting in sightings}


def test_every_code_has_two_dots_so_one_dot_lost_or_added_names_nobody():
    assert len(ROBOT_CODES) == 10 and len(set(ROBOT_CODES)) == 10
    for robot, code in enumerate(ROBOT_CODES):
        lit = tuple(slot in code for slot in range(5))
        assert robot_of_code(lit) == robot
        for slot in range(5):
            flipped = tuple(on != (index == slot) for index, on in enumerate(lit))
            assert robot_of_code(flipped) is None
    assert code_dots(None) == ()
    with pytest.raises(ValueError, match='robots 0 to 9'):
        code_dots(10)


@pytest.mark.parametrize('seed', range(3))
def test_robots_sharing_the_macro_field_are_each_named_where_they_are(seed):
    rng = np.random.default_rng(seed)
    robots = [InView(RobotState(0.0 + 0.04 * k + rng.uniform(-5e-3, 5e-3),
                                rng.uniform(-0.05, 0.05), rng.uniform(-math.pi, math.pi)),
                     int(code)) for k, code in enumerate(rng.choice(10, size=3, replace=False))]
    sightings, reason = identify(frame(MACRO, robots, seed), PlaneMap.nominal(MACRO))
    assert reason == '' and len(sightings) == 3
    named = by_robot(sightings)
    for robot in robots:
        seen = named[robot.code]
        assert math.dist(seen.pose[:2], (robot.motion.x_m, robot.motion.y_m)) < 30e-6
        assert abs(math.remainder(seen.pose[2] - robot.motion.phi_rad, math.tau)) < 0.02


def test_robots_side_by_side_and_moving_at_cruise_speed_are_still_told_apart():
    # Two robots 10 mm apart (their chassis 1 mm apart), both at 14 mm/s across each other.
    robots = [InView(RobotState(0.05, 0.0, 0.3, 0.014, 0.0, 0.2), 4),
              InView(RobotState(0.06, 0.0, 2.0, -0.014, 0.0, -0.2), 5)]
    sightings, _ = identify(frame(MACRO, robots), PlaneMap.nominal(MACRO))
    assert {s.robot for s in sightings} == {4, 5}


def test_an_uncoded_robot_and_two_robots_of_one_code_are_reported_not_named():
    robots = [InView(RobotState(0.02, 0.02, 0.0), None), InView(RobotState(0.05, -0.03, 1.0), 3),
              InView(RobotState(0.09, 0.03, -1.0), 3), InView(RobotState(0.0, -0.04, 0.5), 8)]
    sightings, _ = identify(frame(MACRO, robots), PlaneMap.nominal(MACRO))
    named = [s.robot for s in sightings if s.robot is not None]
    assert named == [8]
    reasons = sorted(s.reason for s in sightings if s.robot is None)
    assert reasons == ["cannot tell apart: its code 00000 is no robot's",
                       'cannot tell apart: two robots read as robot_3',
                       'cannot tell apart: two robots read as robot_3']


def test_a_robot_whose_code_the_field_cuts_is_reported():
    # Its pair whole 3 mm inside the field's top edge (y = 75 mm), its upper code row outside.
    robot = InView(RobotState(0.05, 0.075 - 1.3e-3, 0.0), 2)
    sightings, _ = identify(frame(MACRO, [robot]), PlaneMap.nominal(MACRO))
    assert [(s.robot, s.reason) for s in sightings] == [
        (None, 'cannot tell apart: its code is cut by the edge of the macro field')]


def test_the_micro_camera_names_the_robot_in_its_field_by_the_small_code():
    x, y = MICRO.center_m
    robot = InView(RobotState(x + 50e-6, y - 30e-6, 0.7), 6)
    (sighting,), _ = identify(frame(MICRO, [robot]), PlaneMap.nominal(MICRO))
    assert sighting.robot == 6
    assert math.dist(sighting.pose[:2], (x + 50e-6, y - 30e-6)) < 1e-6


def test_one_uncoded_robot_renders_as_before_and_a_coded_one_tracks_alike():
    motion = RobotState(0.05, 0.01, 0.4)
    plain = render(MACRO, Sensor(), motion, np.random.default_rng(3))
    assert np.array_equal(plain, render_robots(MACRO, Sensor(), [InView(motion)],
                                               np.random.default_rng(3)))
    coded = render_robots(MACRO, Sensor(), [InView(motion, 9)], np.random.default_rng(3))
    assert not np.array_equal(plain, coded)
    pose = track(coded, PlaneMap.nominal(MACRO)).pose
    assert pose is not None and math.dist(pose[:2], (0.05, 0.01)) < 30e-6
    # Two robots in one frame: the single robot's tracker says it cannot choose.
    two = frame(MACRO, [InView(motion, 1), InView(RobotState(0.0, 0.0, 0.0), 2)])
    assert 'ambiguous' in track(two, PlaneMap.nominal(MACRO)).reason
