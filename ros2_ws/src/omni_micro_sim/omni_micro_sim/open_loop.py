"""Open-loop moves from rest, one robot at a time or a batch in parallel.

Each result says where the robot came to rest and where a slip-free robot would have stopped
(:func:`ideal_stop`): the drift the paper's figures plot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim import integrator
from omni_micro_sim.errors import CommandError, SimulationError
from omni_micro_sim.parameters import KERNEL_INDEX, MotorLimits, RobotParameters, require_finite
from omni_micro_sim.profile import WHEEL_COUNT, WheelSpeedProfile, move_profile
from omni_micro_sim.simulator import (
    DEFAULT_MAX_STEP_S,
    DEFAULT_REST_SPEED_M_S,
    STANDING,
    MotionStatus,
    SlipSimulator,
    check_step,
    delayed,
    wheel_offsets,
)
from omni_micro_sim.state import RobotState
from omni_micro_sim.steering import SteeringMotion, plan_steering

DEFAULT_MAX_SETTLE_S = 1.0


_SETTLE_CHECK_INTERVAL_S = 1.0e-3


@dataclass(frozen=True)
class OpenLoopResult:
    """One open-loop move from rest: where it ended and where it should have ended."""

    final_state: RobotState
    ideal_stop_m: tuple[float, float]
    profile_end_s: float
    rest_time_s: float
    trace: dict[str, np.ndarray] | None = None
    steering_time_s: float = 0.0
    final_steering_rad: float = 0.0

    @property
    def drift_m(self) -> float:
        return math.hypot(self.final_state.x_m - self.ideal_stop_m[0],
                          self.final_state.y_m - self.ideal_stop_m[1])


def ideal_stop(params: RobotParameters, start: RobotState, steering_rad: float,
               rotation_rad: float) -> tuple[float, float]:
    """Where a slip-free robot ends: wheel rotation times r along theta (eq. 1 with V_s = 0)."""
    distance = rotation_rad * params.wheel_radius_m
    heading = start.phi_rad + steering_rad
    return (start.x_m + distance * math.cos(heading), start.y_m + distance * math.sin(heading))


def _raise_unless_settled(rest_time: float, state: np.ndarray, max_settle_s: float,
                          what: str) -> None:
    if not math.isfinite(rest_time) or not np.all(np.isfinite(state)):
        raise SimulationError(f'{what} became non-finite')
    if rest_time < 0.0:
        raise SimulationError(f'{what} did not come to rest within {max_settle_s} s of its end')


def run_to_rest(params: RobotParameters, steering_rad: float, profile: WheelSpeedProfile,
                start: RobotState, *, max_step_s: float = DEFAULT_MAX_STEP_S,
                max_settle_s: float = DEFAULT_MAX_SETTLE_S,
                motion: SteeringMotion | None = None) -> tuple[RobotState, float]:
    """Run ``profile`` along ``steering_rad`` from ``start`` until the robot is at rest.

    ``motion`` is the steering before the wheels roll (:func:`steering_motion`); without it the
    wheels stand at ``steering_rad`` already, as the paper has them. ``profile`` is then
    delayed by the steering's duration. Returns the state at rest and the time (s from the
    move's start) it came to rest.

    Raises
    ------
    SimulationError
        If the state became non-finite or the robot did not come to rest in ``max_settle_s``.
    """
    state = start.as_array()
    motion = motion or SteeringMotion.still(steering_rad)
    profile = delayed(profile, motion.duration_s)
    rest_time = integrator.run_move(
        state, profile.knot_times_s, profile.knot_speeds_rad_s, profile.knot_times_s.size,
        motion.wheel_knots, motion.wheel_knots.shape[0], wheel_offsets(params),
        params.as_kernel_array(), check_step('max_step_s', max_step_s),
        DEFAULT_REST_SPEED_M_S, check_step('max_settle_s', max_settle_s),
        _SETTLE_CHECK_INTERVAL_S)
    _raise_unless_settled(rest_time, state, max_settle_s, 'the move')
    return RobotState.from_array(state), rest_time


def steering_motion(params: RobotParameters, steering_rad: float,
                    steer_from_rad: float | None) -> SteeringMotion:
    """The steering before a move from rest: none when the wheels already stand at
    ``steering_rad`` (``steer_from_rad`` None, the paper's case), else from ``steer_from_rad``
    (gear and wheels there)."""
    if steer_from_rad is None:
        return SteeringMotion.still(steering_rad)
    origin = require_finite('steer-from angle', steer_from_rad)
    return plan_steering(params.steering, origin, origin, steering_rad)


def simulate_open_loop(params: RobotParameters, steering_rad: float, duration_s: float, *,
                       limits: MotorLimits | None = None, start: RobotState | None = None,
                       sample_interval_s: float | None = None,
                       max_step_s: float = DEFAULT_MAX_STEP_S,
                       max_settle_s: float = DEFAULT_MAX_SETTLE_S,
                       steer_from_rad: float | None = None) -> OpenLoopResult:
    """The section 3.5 open-loop move: run the profile for ``duration_s``, then wait for rest.

    With ``steer_from_rad`` the wheels first steer from that angle (the paper has them at
    ``steering_rad`` already); ``duration_s`` 0 is then a steering-only move. With
    ``sample_interval_s`` the result carries a trace (time, state, slip, wheel speeds).

    Raises
    ------
    CommandError, ParameterError
        For a malformed move or parameters.
    SimulationError
        If the state became non-finite or the robot did not come to rest in ``max_settle_s``.
    """
    start = start or RobotState()
    steering = require_finite('steering angle', steering_rad)
    if steer_from_rad is not None and duration_s == 0:
        profile = STANDING
    else:
        profile = move_profile(duration_s, limits)
    motion = steering_motion(params, steering, steer_from_rad)
    goal = ideal_stop(params, start, steering, float(profile.rotation_rad()[0]))
    if sample_interval_s is None:
        final, rest_time = run_to_rest(params, steering, profile, start, max_step_s=max_step_s,
                                       max_settle_s=max_settle_s, motion=motion)
        return OpenLoopResult(final, goal, motion.duration_s + profile.end_time_s, rest_time,
                              steering_time_s=motion.duration_s,
                              final_steering_rad=motion.final_wheel_rad)
    interval = check_step('sample_interval_s', sample_interval_s)
    simulator = SlipSimulator(params, start, max_step_s=max_step_s,
                              steering_rad=steering if steer_from_rad is None else steer_from_rad)
    simulator.command(steering, profile)
    profile = simulator.running_profile   # with the steering's delay
    samples: dict[str, list[np.ndarray | float]] = {
        'time_s': [], 'state': [], 'slip_longitudinal_m_s': [], 'slip_transverse_m_s': [],
        'wheel_speed_rad_s': []}

    def record() -> None:
        slip = simulator.slip()
        samples['time_s'].append(simulator.time_s)
        samples['state'].append(simulator.state.as_array())
        samples['slip_longitudinal_m_s'].append(slip.longitudinal_m_s)
        samples['slip_transverse_m_s'].append(slip.transverse_m_s)
        samples['wheel_speed_rad_s'].append(simulator.wheel_speeds())

    record()
    steps = math.ceil(profile.end_time_s / interval - 1e-9)
    for index in range(steps):
        target = min((index + 1) * interval, profile.end_time_s)
        simulator.step(target - simulator.time_s)
        record()
    while simulator.status is not MotionStatus.IDLE:
        if simulator.time_s - profile.end_time_s > max_settle_s:
            raise SimulationError(f'robot still sliding {max_settle_s} s after the move ended')
        simulator.step(interval)
        record()
    trace = {key: np.array(values) for key, values in samples.items()}
    return OpenLoopResult(simulator.state, goal, profile.end_time_s, simulator.time_s, trace,
                          simulator.steering_time_s, simulator.steering_rad)


@dataclass(frozen=True)
class BatchResult:
    final_states: np.ndarray   # (N, 6)
    ideal_stops_m: np.ndarray  # (N, 2)
    rest_times_s: np.ndarray   # (N,)

    @property
    def drifts_m(self) -> np.ndarray:
        drifts: np.ndarray = np.hypot(self.final_states[:, 0] - self.ideal_stops_m[:, 0],
                                      self.final_states[:, 1] - self.ideal_stops_m[:, 1])
        return drifts


def simulate_open_loop_batch(params: RobotParameters | list[RobotParameters],
                             steering_rad: np.ndarray | float,
                             duration_s: np.ndarray | float, *,
                             limits: MotorLimits | None = None, start: RobotState | None = None,
                             max_step_s: float = DEFAULT_MAX_STEP_S,
                             max_settle_s: float = DEFAULT_MAX_SETTLE_S) -> BatchResult:
    """Many open-loop moves at once, in parallel over the cores.

    ``params`` is one robot for all moves or a list with one per move; ``steering_rad`` and
    ``duration_s`` give each move (broadcast against each other).

    Raises
    ------
    SimulationError
        If any move went non-finite or did not come to rest within ``max_settle_s``; the message
        names the move.
    """
    steering, durations = np.broadcast_arrays(np.asarray(steering_rad, dtype=np.float64),
                                              np.asarray(duration_s, dtype=np.float64))
    steering = steering.reshape(-1)
    durations = durations.reshape(-1)
    count = steering.size
    robots = params if isinstance(params, list) else [params] * count
    if len(robots) == 1 and count > 1:
        robots = robots * count
    if len(robots) != count:
        raise CommandError(f'got {len(robots)} parameter sets for {count} moves')
    start = start or RobotState()
    profiles = [move_profile(d, limits) for d in durations]
    knots = max(p.knot_times_s.size for p in profiles)
    knot_times = np.zeros((count, knots))
    knot_speeds = np.zeros((count, knots, WHEEL_COUNT))
    knot_counts = np.zeros(count, dtype=np.int64)
    steer_knots = np.zeros((count, 1, 4))
    steer_counts = np.ones(count, dtype=np.int64)
    offsets = np.zeros((count, WHEEL_COUNT))
    kernel_params = np.zeros((count, len(KERNEL_INDEX)))
    ideal = np.zeros((count, 2))
    for i, (profile, robot) in enumerate(zip(profiles, robots, strict=True)):
        n = profile.knot_times_s.size
        knot_times[i, :n] = profile.knot_times_s
        knot_speeds[i, :n] = profile.knot_speeds_rad_s
        knot_counts[i] = n
        steer = require_finite(f'steering angle of move {i}', steering[i])
        # The wheels stand at the move's angle already (the paper's moves).
        steer_knots[i, 0, 1] = steer
        offsets[i] = wheel_offsets(robot)
        kernel_params[i] = robot.as_kernel_array()
        ideal[i] = ideal_stop(robot, start, steer, float(profile.rotation_rad()[0]))
    states = np.tile(start.as_array(), (count, 1))
    rest_times = np.zeros(count)
    integrator.run_batch(states, knot_times, knot_speeds, knot_counts, steer_knots, steer_counts,
                         offsets, kernel_params,
                         check_step('max_step_s', max_step_s), DEFAULT_REST_SPEED_M_S,
                         check_step('max_settle_s', max_settle_s), _SETTLE_CHECK_INTERVAL_S,
                         rest_times)
    for i in range(count):
        _raise_unless_settled(rest_times[i], states[i], max_settle_s,
                              f'move {i} (steering {steering[i]!r} rad, duration '
                              f'{durations[i]!r} s)')
    return BatchResult(states, ideal, rest_times)
