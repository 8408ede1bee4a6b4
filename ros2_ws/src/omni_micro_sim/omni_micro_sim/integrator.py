"""The robot's motion integrated through its wheel and steering knots (numba): RK4 steps that land
on every knot, the exact arc of a robot in steady rolling, settling to rest, and whole moves,
one or a batch in parallel. The physics it integrates is :mod:`omni_micro_sim.kernels`'.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from omni_micro_sim import knots
from omni_micro_sim.kernels import STATE_SIZE, Array, IntArray, state_derivative, wheel_geometry
from omni_micro_sim.parameters import KERNEL_INDEX

_L = KERNEL_INDEX['wheel_distance_m']

# One definition of the interpolation, compiled here for the integrator.
speeds_at = numba.njit(cache=True)(knots.speeds_at)
steering_at = numba.njit(cache=True)(knots.steering_at)


@numba.njit(cache=True)
def _next_knot_after(time_s: float, knot_times: Array, knot_count: int) -> float:
    for i in range(knot_count):
        if knot_times[i] > time_s:
            return float(knot_times[i])
    return math.inf


# Below this acceleration (m/s^2, and angular acceleration times L) the body has reached the
# steady motion of constant wheel speeds: the rest of the segment is an exact circular arc. The
# error of the jump is about this acceleration times the friction time constant squared: < 1e-15 m.
STEADY_ACCELERATION = 1e-9


@numba.njit(cache=True)
def _sinc(x: float) -> float:
    if abs(x) < 1e-4:
        return 1.0 - x * x / 6.0
    return math.sin(x) / x


@numba.njit(cache=True)
def steady_arc(state: Array, duration: float) -> None:
    """Advance ``state`` in place along the motion with constant body-frame velocity and rate.

    With constant wheel speeds the equations are invariant under rotation, so their steady
    solution keeps its body-frame velocity: the robot runs a circular arc (or a line).
    """
    omega = state[5]
    half_turn = 0.5 * omega * duration
    scale = duration * _sinc(half_turn)
    vx = state[3]
    vy = state[4]
    # The integral over the arc of R(omega*s), applied to the velocity at its start.
    cos_mid = math.cos(half_turn)
    sin_mid = math.sin(half_turn)
    state[0] += scale * (cos_mid * vx - sin_mid * vy)
    state[1] += scale * (sin_mid * vx + cos_mid * vy)
    turn = omega * duration
    cos_turn = math.cos(turn)
    sin_turn = math.sin(turn)
    state[3] = cos_turn * vx - sin_turn * vy
    state[4] = sin_turn * vx + cos_turn * vy
    state[2] += turn


@numba.njit(cache=True)
def _next_steer_knot_after(time_s: float, steer_knots: Array, steer_count: int) -> float:
    for i in range(steer_count):
        if steer_knots[i, 0] > time_s:
            return float(steer_knots[i, 0])
    return math.inf


@numba.njit(cache=True)
def _steering_moves_in(time_s: float, steer_knots: Array, steer_count: int) -> bool:
    i = 0
    while i + 1 < steer_count and steer_knots[i + 1, 0] <= time_s:
        i += 1
    return i < steer_count - 1 and (steer_knots[i, 2] != 0.0 or steer_knots[i, 3] != 0.0)


@numba.njit(cache=True)
def _moving_derivative(state: Array, time_s: float, speeds: Array, steer_knots: Array,
                       steer_count: int, wheel_offsets: Array, params: Array, out: Array,
                       scratch: Array, angles: Array, steer: Array) -> None:
    """The right-hand side while the wheels steer: their directions change with time."""
    steering_at(time_s, steer_knots, steer_count, steer)
    for k in range(3):
        angles[k] = steer[0] + wheel_offsets[k]
    state_derivative(state, speeds, steer[1], wheel_geometry(angles, params), params, out,
                     scratch)


@numba.njit(cache=True)
def advance(state: Array, t_from: float, t_to: float, knot_times: Array, knot_speeds: Array,
            knot_count: int, steer_knots: Array, steer_count: int, wheel_offsets: Array,
            params: Array, max_step: float) -> bool:
    """Integrate ``state`` in place from ``t_from`` to ``t_to`` (move time) with classical RK4.

    The wheels roll along psi(t) + xi_k, psi from ``steer_knots``, xi_k in ``wheel_offsets``.
    Steps never straddle a knot of either, where an acceleration jumps, so each step integrates
    a smooth right-hand side; steps are at most ``max_step`` long. Returns False if the state
    became non-finite.
    """
    k1 = np.empty(STATE_SIZE)
    k2 = np.empty(STATE_SIZE)
    k3 = np.empty(STATE_SIZE)
    k4 = np.empty(STATE_SIZE)
    trial = np.empty(STATE_SIZE)
    speeds = np.empty(3)
    scratch = np.empty((4, 3))
    speeds_end = np.empty(3)
    angles = np.empty(3)
    steer = np.empty(2)
    time_s = t_from
    while t_to - time_s > 1e-15 * max(1.0, abs(t_to)):
        segment_end = min(_next_knot_after(time_s, knot_times, knot_count),
                          _next_steer_knot_after(time_s, steer_knots, steer_count), t_to)
        span = segment_end - time_s
        # int(): numba's math.ceil returns a float.
        steps = max(1, int(math.ceil(span / max_step - 1e-9)))  # noqa: RUF046
        h = span / steps
        start = time_s
        if _steering_moves_in(start, steer_knots, steer_count):
            for j in range(steps):
                t = start + j * h
                speeds_at(t, knot_times, knot_speeds, knot_count, speeds)
                _moving_derivative(state, t, speeds, steer_knots, steer_count, wheel_offsets,
                                   params, k1, scratch, angles, steer)
                for q in range(STATE_SIZE):
                    trial[q] = state[q] + 0.5 * h * k1[q]
                speeds_at(t + 0.5 * h, knot_times, knot_speeds, knot_count, speeds)
                _moving_derivative(trial, t + 0.5 * h, speeds, steer_knots, steer_count,
                                   wheel_offsets, params, k2, scratch, angles, steer)
                for q in range(STATE_SIZE):
                    trial[q] = state[q] + 0.5 * h * k2[q]
                _moving_derivative(trial, t + 0.5 * h, speeds, steer_knots, steer_count,
                                   wheel_offsets, params, k3, scratch, angles, steer)
                for q in range(STATE_SIZE):
                    trial[q] = state[q] + h * k3[q]
                speeds_at(t + h, knot_times, knot_speeds, knot_count, speeds)
                _moving_derivative(trial, t + h, speeds, steer_knots, steer_count,
                                   wheel_offsets, params, k4, scratch, angles, steer)
                for q in range(STATE_SIZE):
                    state[q] += h / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])
        else:
            steering_at(start, steer_knots, steer_count, steer)
            for k in range(3):
                angles[k] = steer[0] + wheel_offsets[k]
            geometry = wheel_geometry(angles, params)
            speeds_at(start, knot_times, knot_speeds, knot_count, speeds)
            steady_speeds = True
            speeds_at(segment_end, knot_times, knot_speeds, knot_count, speeds_end)
            for k in range(3):
                if speeds_end[k] != speeds[k]:
                    steady_speeds = False
            for j in range(steps):
                t = start + j * h
                speeds_at(t, knot_times, knot_speeds, knot_count, speeds)
                state_derivative(state, speeds, 0.0, geometry, params, k1, scratch)
                # Steady when the velocity only turns with the body: a = omega x v.
                if steady_speeds and math.hypot(k1[3] + state[5] * state[4],
                                                k1[4] - state[5] * state[3]) \
                        < STEADY_ACCELERATION \
                        and abs(k1[5]) * params[_L] < STEADY_ACCELERATION:
                    steady_arc(state, segment_end - t)
                    break
                for q in range(STATE_SIZE):
                    trial[q] = state[q] + 0.5 * h * k1[q]
                speeds_at(t + 0.5 * h, knot_times, knot_speeds, knot_count, speeds)
                state_derivative(trial, speeds, 0.0, geometry, params, k2, scratch)
                for q in range(STATE_SIZE):
                    trial[q] = state[q] + 0.5 * h * k2[q]
                state_derivative(trial, speeds, 0.0, geometry, params, k3, scratch)
                for q in range(STATE_SIZE):
                    trial[q] = state[q] + h * k3[q]
                speeds_at(t + h, knot_times, knot_speeds, knot_count, speeds)
                state_derivative(trial, speeds, 0.0, geometry, params, k4, scratch)
                for q in range(STATE_SIZE):
                    state[q] += h / 6.0 * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q])
        for q in range(STATE_SIZE):
            if not math.isfinite(state[q]):
                return False
        time_s = segment_end
    return True


@numba.njit(cache=True)
def is_at_rest(state: Array, params: Array, rest_speed: float) -> bool:
    """Translation and the rotation's rim speed at the wheels both under ``rest_speed`` (m/s)."""
    speed = math.hypot(state[3], state[4])
    return speed < rest_speed and abs(state[5]) * params[_L] < rest_speed


@numba.njit(cache=True)
def settle(state: Array, t_from: float, knot_times: Array, knot_speeds: Array,
           knot_count: int, steer_knots: Array, steer_count: int, wheel_offsets: Array,
           params: Array, max_step: float, rest_speed: float, max_settle_s: float,
           check_interval_s: float) -> float:
    """Integrate from ``t_from`` (after the last knot) until the robot is at rest.

    Returns the move time at which it was first seen at rest, or -1 if it did not come to rest
    within ``max_settle_s``, or NaN if the state became non-finite.
    """
    time_s = t_from
    while not is_at_rest(state, params, rest_speed):
        if time_s - t_from >= max_settle_s:
            return -1.0
        if not advance(state, time_s, time_s + check_interval_s, knot_times, knot_speeds,
                       knot_count, steer_knots, steer_count, wheel_offsets, params, max_step):
            return math.nan
        time_s += check_interval_s
    return time_s


@numba.njit(cache=True)
def run_move(state: Array, knot_times: Array, knot_speeds: Array, knot_count: int,
             steer_knots: Array, steer_count: int, wheel_offsets: Array, params: Array,
             max_step: float, rest_speed: float, max_settle_s: float,
             check_interval_s: float) -> float:
    """One open-loop move: advance ``state`` through its steering and profile, then settle."""
    end = max(knot_times[knot_count - 1], steer_knots[steer_count - 1, 0])
    if not advance(state, 0.0, end, knot_times, knot_speeds, knot_count, steer_knots,
                   steer_count, wheel_offsets, params, max_step):
        return math.nan
    return settle(state, end, knot_times, knot_speeds, knot_count, steer_knots, steer_count,
                  wheel_offsets, params, max_step, rest_speed, max_settle_s, check_interval_s)


@numba.njit(cache=True, parallel=True)
def run_batch(states: Array, knot_times: Array, knot_speeds: Array, knot_counts: IntArray,
              steer_knots: Array, steer_counts: IntArray, wheel_offsets: Array, params: Array,
              max_step: float, rest_speed: float, max_settle_s: float,
              check_interval_s: float, rest_times: Array) -> None:
    """:func:`run_move` for every row of ``states``, in parallel; results in ``rest_times``."""
    for i in numba.prange(states.shape[0]):
        rest_times[i] = run_move(states[i], knot_times[i], knot_speeds[i], knot_counts[i],
                                 steer_knots[i], steer_counts[i], wheel_offsets[i], params[i],
                                 max_step, rest_speed, max_settle_s, check_interval_s)
