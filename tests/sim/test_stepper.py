"""The grid simulator and the wheel command contract: exact sim-time execution, rejections."""

import math

import numpy as np
import pytest

from omni_micro_common.conventions import JOINT_NAMES
from omni_micro_sim import paper
from omni_micro_sim.errors import CommandError
from omni_micro_sim.open_loop import simulate_open_loop
from omni_micro_sim.parameters import MotorLimits, RobotParameters
from omni_micro_sim.profile import WheelCommand, move_profile
from omni_micro_sim.simulator import MotionStatus, SlipSimulator
from omni_micro_sim.stepper import GridSimulator
from omni_micro_sim.wheel_trajectory import (
    TrajectoryPoint,
    command_from_points,
    points_from_profile,
)

ROBOT = paper.FIG8.robot()


def run_until_idle(grid: GridSimulator, limit_s: float = 5.0):
    while grid.time_s < limit_s:
        sample = grid.advance()
        if grid.pending is None and sample.status is MotionStatus.IDLE:
            return sample
    raise AssertionError('robot did not come to rest')


def test_command_starts_at_its_stamp_on_the_grid_and_runs_in_full():
    grid = GridSimulator(ROBOT, period_s=0.02)
    scheduled = grid.schedule(WheelCommand(0.05, 0.0, move_profile(2.0)))
    assert scheduled.start_s == pytest.approx(0.06) and scheduled.late_by_s == 0.0
    final = run_until_idle(grid)
    # Same physics as the open-loop core: the start time does not change where it stops.
    reference = simulate_open_loop(ROBOT, 0.0, 2.0).final_state
    assert final.state.x_m == pytest.approx(reference.x_m, abs=1e-10)
    assert final.state.y_m == pytest.approx(reference.y_m, abs=1e-10)
    assert final.wheel_rotations_rad == pytest.approx(np.full(3, 8.7 * 2.0))


def test_loading_the_kernels_changes_nothing_of_the_run():
    """The dynamics node loads the kernels before time starts by integrating a move on a copy:
    the grid keeps its time, its queue and its robot."""
    loaded, fresh = GridSimulator(ROBOT, period_s=0.02), GridSimulator(ROBOT, period_s=0.02)
    command = WheelCommand(0.04, 0.3, move_profile(0.5))
    for grid in (loaded, fresh):
        grid.schedule(command)
    loaded.load_kernels()
    assert loaded.tick == 0 and loaded.pending is command
    for _ in range(40):
        ours, theirs = loaded.advance(), fresh.advance()
        assert ours.state == theirs.state and ours.steering_rad == theirs.steering_rad


def test_late_command_starts_now_and_says_how_late():
    grid = GridSimulator(ROBOT, period_s=0.02)
    for _ in range(10):
        grid.advance()
    scheduled = grid.schedule(WheelCommand(0.1, 0.0, move_profile(0.2)))
    assert scheduled.start_s == pytest.approx(0.2)
    assert scheduled.late_by_s == pytest.approx(0.1)


def test_stop_ramps_down_at_the_motor_deceleration():
    grid = GridSimulator(ROBOT, period_s=0.02)
    grid.schedule(WheelCommand(0.0, 0.0, move_profile(5.0)))
    for _ in range(25):
        grid.advance()
    grid.schedule_stop()
    speeds = [grid.advance().wheel_speeds_rad_s[1] for _ in range(12)]
    assert speeds[0] == pytest.approx(8.7 - 50 * 0.02)
    assert speeds[-1] == 0.0


def trajectory(profile_duration=0.5, steering=0.3):
    return points_from_profile(steering, move_profile(profile_duration))


def test_trajectory_round_trip_keeps_the_profile():
    points = trajectory()
    command = command_from_points(list(reversed(JOINT_NAMES)),
                                  [TrajectoryPoint(p.time_from_start_s, p.positions[::-1],
                                                   p.velocities[::-1]) for p in points],
                                  1.0, 0.5, MotorLimits())
    assert command.start_s == 1.0 and command.steering_rad == 0.3
    assert command.profile is not None
    assert command.profile.rotation_rad() == pytest.approx(np.full(3, 8.7 * 0.5))


def test_empty_trajectory_is_a_stop_now():
    command = command_from_points(JOINT_NAMES, [], 0.0, 2.5, MotorLimits())
    assert command.is_stop and command.start_s == 2.5


def broken(change):
    points = [TrajectoryPoint(p.time_from_start_s, list(p.positions), list(p.velocities))
              for p in trajectory()]
    names = list(JOINT_NAMES)
    change(names, points)
    return names, points


@pytest.mark.parametrize('change, message', [
    (lambda n, p: n.__setitem__(1, 'wheel_9_joint'), 'joint names'),
    (lambda n, p: p[1].velocities.__setitem__(2, math.nan), 'non-finite'),
    (lambda n, p: p.__setitem__(0, TrajectoryPoint(-0.1, p[0].positions, p[0].velocities)),
     'first point'),
    (lambda n, p: p.__setitem__(2, TrajectoryPoint(p[1].time_from_start_s, p[2].positions,
                                                   p[2].velocities)), 'increase strictly'),
    (lambda n, p: p[1].velocities.__setitem__(1, 20.0), 'exceeds the motor limit'),
    (lambda n, p: p[-1].velocities.__setitem__(3, 1.0), 'last point must stop'),
    (lambda n, p: p[1].positions.__setitem__(0, 0.5), 'steering must stay'),
    (lambda n, p: p[1].positions.pop(), 'positions and velocities'),
])
def test_malformed_trajectories_are_rejected_with_the_reason(change, message):
    names, points = broken(change)
    with pytest.raises(CommandError, match=message):
        command_from_points(names, points, 0.0, 0.0, MotorLimits())


def test_rejected_command_leaves_nothing_queued():
    grid = GridSimulator(ROBOT)
    too_fast = move_profile(1.0, MotorLimits(cruise_speed_rad_s=12.0, max_speed_rad_s=12.0))
    with pytest.raises(CommandError):
        grid.schedule(WheelCommand(0.0, 0.0, too_fast))
    assert grid.pending is None


def test_the_wheel_contract_refuses_a_trajectory_too_long_or_an_angle_no_float_holds():
    """10,000 valid points once slowed dynamics_node from 50 ticks a second to one; 1e20 rad
    of steering was taken without a word (no float holds it to a fraction of a turn)."""
    from omni_micro_sim.wheel_trajectory import MAX_POINTS

    move = points_from_profile(0.3, move_profile(1.0))
    assert command_from_points(JOINT_NAMES, move, 0.0, 0.0, MotorLimits()).steering_rad == 0.3
    many = [TrajectoryPoint(k * 1e-3, [0.0] * 4, [0.0] * 4) for k in range(MAX_POINTS + 1)]
    with pytest.raises(CommandError, match=r'a trajectory of 1001 points: at most 1000'):
        command_from_points(JOINT_NAMES, many, 0.0, 0.0, MotorLimits())
    far = [TrajectoryPoint(p.time_from_start_s, [1e20, *p.positions[1:]], p.velocities)
           for p in move]
    with pytest.raises(CommandError, match=r'steering angle 1e\+20 rad: expected within \+-2 pi'):
        command_from_points(JOINT_NAMES, far, 0.0, 0.0, MotorLimits())


def test_a_robot_moved_and_turned_mid_move_goes_on_the_same_way_moved_and_turned():
    """What an estimator's correction relies on: the floor is the same everywhere, so a robot
    shifted by (dx, dy) and turned by dphi about its centre rolls on shifted and turned."""
    robot = RobotParameters(wheel_offsets_rad=(0.0, math.radians(3.0), math.radians(2.0)))
    rolling = SlipSimulator(robot)
    rolling.command(0.3, move_profile(5.0))
    rolling.step(0.7)
    before = rolling.state
    moved = rolling.with_robot(robot)
    dx, dy, dphi = 2e-4, -1e-4, 0.05
    moved.move_by(dx, dy, dphi)
    rolling.step(1.9)
    moved.step(1.9)
    here, there = rolling.state, moved.state
    cos_d, sin_d = math.cos(dphi), math.sin(dphi)
    ex, ey = here.x_m - before.x_m, here.y_m - before.y_m
    assert there.x_m == pytest.approx(before.x_m + dx + cos_d * ex - sin_d * ey, abs=1e-12)
    assert there.y_m == pytest.approx(before.y_m + dy + sin_d * ex + cos_d * ey, abs=1e-12)
    assert there.phi_rad == pytest.approx(here.phi_rad + dphi, abs=1e-12)
    # Another robot from the same instant: the copy rolls on with its own offsets.
    other = rolling.with_robot(RobotParameters())
    other.step(0.5)
    rolling.step(0.5)
    assert abs(other.state.y_m - rolling.state.y_m) > 1e-6
