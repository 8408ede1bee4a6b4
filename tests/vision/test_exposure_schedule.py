"""When a simulated camera's frames are due and where each robot stands in them: 30 Hz frames on
the 50 Hz grid, each once, each robot where it was at the exposure's start; a late camera makes up
no past frame; a fleet's frame waits for every robot's odometry."""

from __future__ import annotations

import math

import pytest

from omni_micro_sim.state import RobotState
from omni_micro_vision.exposure_schedule import ExposureSchedule

TICK_S = 0.02
RATE_HZ = 30.0


def rolling(x0_m: float, speed_m_s: float, time_s: float) -> RobotState:
    """A robot rolling along x at constant speed, turning at 1 rad/s."""
    return RobotState(x0_m + speed_m_s * time_s, 0.0, time_s, speed_m_s, 0.0, 1.0)


def test_each_frame_once_with_the_robot_where_it_was_when_the_exposure_started():
    schedule = ExposureSchedule(RATE_HZ, [None])
    frames = []
    for tick in range(16):   # 0 .. 0.3 s
        frames += schedule.on_sample(0, tick * TICK_S, rolling(0.0, 0.01, tick * TICK_S))
    assert [number for number, _ in frames] == list(range(10))   # 0 .. 0.3 s at 30 Hz
    for number, (robot,) in frames:
        frame_s = number / RATE_HZ
        assert robot.code is None
        # Between the samples either side: exact for a constant speed and turn.
        assert robot.motion.x_m == pytest.approx(0.01 * frame_s, abs=1e-15)
        assert robot.motion.phi_rad == pytest.approx(frame_s, abs=1e-12)


def test_a_camera_started_late_makes_up_no_frame_of_the_past():
    schedule = ExposureSchedule(RATE_HZ, [None])
    first = schedule.on_sample(0, 1.0, rolling(0.0, 0.0, 1.0))
    assert [number for number, _ in first] == [30]   # not 0 .. 29
    assert [number for number, _ in schedule.on_sample(0, 1.02, rolling(0.0, 0.0, 1.02))] == []
    assert [number for number, _ in schedule.on_sample(0, 1.04, rolling(0.0, 0.0, 1.04))] == [31]


def test_a_frame_of_several_robots_waits_for_every_robot_and_shows_each_at_its_time():
    schedule = ExposureSchedule(RATE_HZ, [0, 3])
    # Robot 0's odometry arrives first, 0 .. 0.1 s: nothing is due while robot 3 has sent none.
    for tick in range(6):
        assert schedule.on_sample(0, tick * TICK_S, rolling(0.01, 0.01, tick * TICK_S)) == []
    assert schedule.reached_s is None
    due = []
    for tick in range(6):
        due += schedule.on_sample(1, tick * TICK_S, rolling(0.05, -0.02, tick * TICK_S))
        assert schedule.reached_s == pytest.approx(tick * TICK_S)
    assert [number for number, _ in due] == [0, 1, 2, 3]   # up to 0.1 s, each once
    for number, (first, second) in due:
        frame_s = number / RATE_HZ
        assert (first.code, second.code) == (0, 3)
        assert first.motion.x_m == pytest.approx(0.01 + 0.01 * frame_s, abs=1e-15)
        assert second.motion.x_m == pytest.approx(0.05 - 0.02 * frame_s, abs=1e-15)
        assert math.isclose(second.motion.phi_rad, frame_s, abs_tol=1e-12)
