"""The guard of several real robots on the bench (omni_micro_control.fleet_guard): robots seen
at a camera's 15 Hz, stopped before two centres come under the stop gap, and a robot driving
unnamed stopped after the bound; planned passes at the clearance never stopped."""

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from omni_micro_control.fleet_guard import (
    CONTACT_GAP_M,
    HORIZON_S,
    STOP_GAP_M,
    UNNAMED_S,
    FleetGuard,
)

FRAME_S = 1.0 / 15.0
CRUISE_M_S = 14e-3     # the paper's robot: 100 mm in about 7 s


def drive(guard, paths, frames, latency_s=0.0):
    """Feed ``paths`` (robot -> t -> (x, y)) at the camera's rate; the first stop and when."""
    for frame in range(frames):
        t = frame * FRAME_S
        for robot, path in paths.items():
            guard.saw(robot, t, *path(t), arrived_s=t + latency_s)
        stop = guard.check(t + latency_s, stamps_now_s=t + latency_s)
        if stop is not None:
            return stop, t
    return None, None


def test_two_still_robots_at_the_clearance_are_left_alone():
    guard = FleetGuard(2)
    stop, _ = drive(guard, {0: lambda t: (0.0, 0.0), 1: lambda t: (0.012, 0.0)}, 60)
    assert stop is None
    assert guard.closest_gap_m == pytest.approx(0.012) and guard.closest_pair == (0, 1)


def test_a_robot_driven_at_a_still_one_is_stopped_with_room_for_the_stop():
    guard = FleetGuard(2)
    stop, at = drive(guard, {0: lambda t: (0.0, 0.0), 1: lambda t: (0.030 - CRUISE_M_S * t, 0.0)},
                     60)
    assert stop is not None and stop.kind == 'proximity' and stop.robots == (0, 1)
    gap = 0.030 - CRUISE_M_S * at
    # At the first frame whose projection over the horizon crosses the stop gap: no sooner
    # than needed, and the robot has the rest of the horizon to stop in.
    reach = STOP_GAP_M + CRUISE_M_S * HORIZON_S
    assert reach - CRUISE_M_S * FRAME_S <= gap < reach
    assert 'robot_0 and robot_1' in stop.reason and 'closing at 14.0 mm/s' in stop.reason
    assert 'within 0.20 s (9 mm discs; seen 0.00 s ago)' in stop.reason


@pytest.mark.parametrize('latency_s', [0.1, 0.25, 0.4])
def test_captures_that_arrive_late_stop_the_robots_sooner_by_their_age(latency_s):
    """On a busy machine a capture arrives old: the robots have closed further than it says,
    and the stop is sent that much sooner, so the robots have the same room to stop in."""
    guard = FleetGuard(2)
    speed = 2 * CRUISE_M_S
    stop, at = drive(guard, {0: lambda t: (speed * t, 0.0), 1: lambda t: (0.050, 0.0)}, 60,
                     latency_s=latency_s)
    assert stop is not None
    gap_when_sent = 0.050 - speed * (at + latency_s)
    reach = STOP_GAP_M + speed * HORIZON_S
    assert reach - speed * FRAME_S <= gap_when_sent < reach
    assert f'seen {latency_s:.2f} s ago' in stop.reason


def stalled_tracker(wheels_turn):
    """Robot 1 driven at cruise at robot 0, which stands; frames 15 Hz, each capture arriving
    0.45 s after its stamp until the tracker stalls on the frames from 0.5 s (it catches up at
    2 s). Checked every 20 ms, each robot's wheels reported then (robot 1's turning, if
    ``wheels_turn``): the first stop, and when."""
    guard = FleetGuard(2)
    latency_s = 0.45
    stamps = [frame * FRAME_S for frame in range(40)]
    arrivals = sorted((t + latency_s if t < 0.5 else 2.0, t) for t in stamps)
    for tick in range(120):
        now = tick * WHEELS_S
        while arrivals and arrivals[0][0] <= now:
            arrived, t = arrivals.pop(0)
            guard.saw(0, t, 0.0, 0.0, arrived_s=arrived)
            guard.saw(1, t, 0.030 - CRUISE_M_S * t, 0.0, arrived_s=arrived)
        if wheels_turn:
            guard.wheels(0, False, arrived_s=now)
            guard.wheels(1, True, arrived_s=now)
        stop = guard.check(now, stamps_now_s=now)
        if stop is not None:
            return stop, now
    return None, None


def test_a_robot_whose_wheels_turn_goes_on_in_the_guard_s_eyes_while_its_captures_stall():
    """Its captures stalled, a robot whose wheels turn is taken to drive on as they last said,
    however old they grow: stopped with the horizon's room left (once, cut off at 0.5 s, it
    drove on unstopped until the next capture, and touched)."""
    stop, at = stalled_tracker(wheels_turn=True)
    assert stop is not None and stop.kind == 'proximity' and stop.robots == (0, 1)
    gap_when_sent = 0.030 - CRUISE_M_S * at
    reach = STOP_GAP_M + CRUISE_M_S * HORIZON_S
    assert reach - CRUISE_M_S * WHEELS_S <= gap_when_sent < reach
    assert at < 2.0 and 'seen 0.7' in stop.reason
    # Without word that its wheels turn, its velocity holds 0.5 s: the stop waits for news.
    stop, at = stalled_tracker(wheels_turn=False)
    assert stop is not None and at == pytest.approx(2.0)


def test_two_robots_head_on_are_stopped_sooner():
    guard = FleetGuard(2)
    stop, at = drive(guard, {0: lambda t: (CRUISE_M_S * t, 0.0),
                             1: lambda t: (0.040 - CRUISE_M_S * t, 0.0)}, 60)
    assert stop is not None and stop.kind == 'proximity'
    reach = STOP_GAP_M + 2 * CRUISE_M_S * HORIZON_S
    assert reach - 2 * CRUISE_M_S * FRAME_S <= 0.040 - 2 * CRUISE_M_S * at < reach


def test_planned_passes_on_lanes_at_the_clearance_are_never_stopped():
    """Two robots passing each other at cruise on lanes 12 mm apart (the planner's pitch), and
    one parked 12 mm beyond another's goal that it ramps down to."""
    guard = FleetGuard(2)
    stop, _ = drive(guard, {0: lambda t: (CRUISE_M_S * t, 0.0),
                            1: lambda t: (0.060 - CRUISE_M_S * t, 0.012)}, 90)
    assert stop is None and guard.closest_gap_m == pytest.approx(0.012, abs=1e-3)

    def ramping(t):   # at cruise, then down to rest at its goal x = 0 in 0.17 s
        ramp = 0.174
        stop_at = 1.5
        if t < stop_at - ramp:
            return (-CRUISE_M_S * (stop_at - ramp / 2 - t), 0.0)
        left = max(stop_at - t, 0.0)
        return (-CRUISE_M_S * left * left / (2 * ramp), 0.0)

    guard = FleetGuard(2)
    stop, _ = drive(guard, {0: ramping, 1: lambda t: (0.012, 0.0)}, 60)
    assert stop is None


@settings(max_examples=300, deadline=None)
@given(speed=st.floats(1e-3, 30e-3), miss=st.floats(0.0, 20e-3),
       angle=st.floats(0.0, 2 * math.pi), phase=st.floats(0.0, FRAME_S))
def test_no_pass_under_the_stop_gap_goes_unstopped(speed, miss, angle, phase):
    """Whatever their closing speed (up to two robots at twice cruise) and how wide they would
    pass, two robots seen at 15 Hz are stopped before their centres come under the stop gap,
    however the frames fall."""
    direction = (math.cos(angle), math.sin(angle))
    normal = (-direction[1], direction[0])

    def mover(t):
        along = -0.05 + speed * (t + phase)
        return (along * direction[0] + miss * normal[0], along * direction[1] + miss * normal[1])

    guard = FleetGuard(2)
    frames = int((0.1 / speed) / FRAME_S) + 2
    stop, at = drive(guard, {0: lambda t: (0.0, 0.0), 1: mover}, frames)
    closest_after = min(math.hypot(*mover(at + k * 1e-3)) for k in range(200)) \
        if stop else miss
    if miss < STOP_GAP_M:
        assert stop is not None
    if stop is None:
        assert miss >= STOP_GAP_M
    else:
        # Stopped while the gap was still above the stop gap.
        assert math.hypot(*mover(at)) >= STOP_GAP_M
        assert closest_after > CONTACT_GAP_M or math.hypot(*mover(at)) >= STOP_GAP_M


def test_a_robot_driving_unnamed_is_stopped_after_the_bound_and_one_parked_is_not():
    guard = FleetGuard(3)
    for frame in range(10):
        t = frame * FRAME_S
        for robot in range(3):
            guard.saw(robot, t, 0.02 * robot, 0.0, arrived_s=t)
    last = 9 * FRAME_S
    guard.driving(1, now_s=0.0)
    # Robot 2 parked and unseen is no one's concern; robot 1 driving is, after the bound.
    assert guard.check(last + UNNAMED_S - 0.01) is None
    stop = guard.check(last + UNNAMED_S + 0.01)
    assert stop is not None and stop.kind == 'unnamed' and stop.robots == (1,)
    assert stop.reason.startswith('robot_1 drove unnamed by the cameras for 1.01 s')
    assert 'last named at (20.0, 0.0) mm' in stop.reason
    guard.driving(1, now_s=0.0, driving=False)
    assert guard.check(last + 10.0) is None


WHEELS_S = 0.02   # a driver's joint states at 50 Hz (joint_state_broadcaster)


def report_wheels(guard, robot, start_s, end_s, turning):
    """The robot's driver reporting its wheels ``turning`` (or standing) from ``start_s`` to
    ``end_s``; whether the guard stopped every robot meanwhile, and when."""
    for tick in range(round((end_s - start_s) / WHEELS_S) + 1):
        now = start_s + tick * WHEELS_S
        guard.wheels(robot, turning, arrived_s=now)
        stop = guard.check(now)
        if stop is not None:
            return stop, now
    return None, None


def test_a_robot_standing_unnamed_is_left_alone_and_stopped_once_its_wheels_turned_the_bound():
    """The paper's rule stands still between moves, waiting for a capture: a slow camera is no
    danger then. Only the time its wheels turn unnamed counts, over every move since it was
    last named: 0.4 s, standing 2 s, 0.7 s more."""
    guard = FleetGuard(2)
    guard.saw(1, 0.0, 0.02, 0.0, arrived_s=0.0)
    guard.driving(1, now_s=0.0)
    assert report_wheels(guard, 1, 0.0, 0.4, turning=True) == (None, None)
    assert report_wheels(guard, 1, 0.42, 2.4, turning=False) == (None, None)
    stop, at = report_wheels(guard, 1, 2.42, 4.0, turning=True)
    assert stop is not None and stop.kind == 'unnamed' and stop.robots == (1,)
    assert at == pytest.approx(2.42 + 0.62, abs=WHEELS_S + 1e-9)
    assert stop.reason.startswith('robot_1 drove unnamed by the cameras for 1.0')
    # Named again, the count starts over.
    guard.saw(1, 4.0, 0.03, 0.0, arrived_s=4.0)
    assert report_wheels(guard, 1, 4.0, 4.9, turning=True) == (None, None)


def test_a_robot_whose_driver_falls_silent_counts_all_its_time_unnamed():
    """Its wheels last said standing, then nothing: after the bound, all the time since it was
    named counts, as without word from its wheels."""
    guard = FleetGuard(2)
    guard.saw(0, 0.0, 0.0, 0.0, arrived_s=0.0)
    guard.driving(0, now_s=0.0)
    guard.wheels(0, turning=False, arrived_s=0.1)
    assert guard.check(1.05) is None          # its latest state is recent, and standing
    stop = guard.check(1.15)                  # nothing from its wheels for over 1 s
    assert stop is not None and stop.reason.startswith(
        'robot_0 drove unnamed by the cameras for 1.15 s')


def test_a_robot_given_a_leg_before_any_capture_is_stopped_as_never_named():
    guard = FleetGuard(2)
    guard.driving(0, now_s=5.0)
    assert guard.check(5.0 + UNNAMED_S) is None
    stop = guard.check(5.0 + UNNAMED_S + 0.5)
    assert stop is not None and 'never named' in stop.reason


def test_a_late_capture_does_not_move_a_robot_back():
    guard = FleetGuard(2)
    guard.saw(0, 1.0, 0.0, 0.0, arrived_s=1.0)
    guard.saw(1, 1.0, 0.05, 0.0, arrived_s=1.0)
    guard.saw(1, 0.5, 0.0101, 0.0, arrived_s=1.1)    # older than its latest: a sign of life
    assert guard.check(1.1) is None and guard.closest_gap_m == pytest.approx(0.05)


@pytest.mark.parametrize(('name', 'value', 'said'), [
    ('stop_gap_m', 0.005, 'at least the contact gap 9 mm'),
    ('horizon_s', -1.0, 'horizon_s must be a positive number, got -1.0'),
    ('unnamed_s', math.nan, 'unnamed_s must be a positive number, got nan')])
def test_bad_settings_are_refused_naming_them(name, value, said):
    with pytest.raises(ValueError, match=said):
        FleetGuard(2, **{name: value})


def test_a_robot_seen_away_from_its_planned_start_is_said_with_both_places():
    guard = FleetGuard(3)
    guard.saw(0, 1.0, 0.0201, 0.0, arrived_s=1.0)      # 0.1 mm off: where it was put
    guard.saw(1, 1.0, 0.0220, 0.030, arrived_s=1.0)    # 2 mm off: another place
    assert guard.misplaced([(0.020, 0.0), (0.020, 0.030), (0.050, 0.0)]) == [
        'robot_1 stands at (22.00, 30.00) mm, 2.00 mm from its start (20, 30) mm']



def test_frames_read_back_to_back_by_a_busy_driver_give_no_false_closing():
    """A driver that stamps a frame when it reads it (usb_cam's default) on a busy machine
    reads every other frame late, just before the next: two frames 2 ms apart by their stamps
    with a frame's travel (0.93 mm at cruise) between them, 465 mm/s taken at its word. A robot
    driven at cruise toward one parked 30 mm on, stopping 23 mm short, is left alone; one that
    heads on into it is still stopped."""
    def read_late(paths, frames):
        guard = FleetGuard(2)
        for frame in range(frames):
            exposed = frame * FRAME_S
            stamp = exposed + (FRAME_S - 0.002 if frame % 2 else 0.0)
            for robot, path in paths.items():
                x_m, y_m = path(exposed)
                guard.saw(robot, stamp, x_m, y_m, arrived_s=stamp)
            stop = guard.check(stamp, stamps_now_s=stamp)
            if stop is not None:
                return stop
        return None

    short = 0.5   # s of cruise: 7 mm
    parked = {0: lambda t: (CRUISE_M_S * min(t, short), 0.0), 1: lambda t: (0.030, 0.0)}
    assert read_late(parked, 30) is None
    head_on = {0: lambda t: (CRUISE_M_S * t, 0.0), 1: lambda t: (0.030, 0.0)}
    stop = read_late(head_on, 60)
    assert stop is not None and stop.kind == 'proximity'


def test_the_stop_says_the_gap_the_projection_started_from():
    """Robot 1, its wheels turning, goes unnamed (hidden) while driving at robot 0, which the
    camera still names every frame: the guard carries robot 1 on at its velocity, and the stop
    says the gap it carried it to, not where robot 1 was half a second after it was last
    seen (27.4 mm: once, the message said so)."""
    guard = FleetGuard(2)
    stop = None
    for frame in range(60):
        t = frame * FRAME_S
        guard.saw(0, t, 0.0, 0.0, arrived_s=t)
        if t <= 0.4:
            guard.saw(1, t, 0.040 - CRUISE_M_S * t, 0.0, arrived_s=t)
        guard.wheels(0, False, arrived_s=t)
        guard.wheels(1, True, arrived_s=t)
        stop = guard.check(t, stamps_now_s=t)
        if stop is not None:
            break
    assert stop is not None and stop.kind == 'proximity', stop
    said_mm = float(stop.reason.split(' mm apart')[0].rsplit(' ', 1)[1])
    carried_on_mm = (0.040 - CRUISE_M_S * t) * 1e3
    assert said_mm == pytest.approx(carried_on_mm, abs=0.01)
    assert said_mm < STOP_GAP_M * 1e3 + CRUISE_M_S * (HORIZON_S + FRAME_S) * 1e3
