"""Piecewise-linear wheel speeds and piecewise-quadratic steering between knots, in plain Python
(no numba import).

:mod:`kernels` compiles :func:`speeds_at` and :func:`steering_at` for the integrator; the
controller builds its commands with these as they are, so that the paper's mode never loads
numba.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

Array = npt.NDArray[np.float64]


def speeds_at(time_s: float, knot_times: Array, knot_speeds: Array, knot_count: int,
              out: Array) -> None:
    """Piecewise-linear wheel speeds at ``time_s``; constant outside the knots."""
    if time_s <= knot_times[0]:
        for k in range(3):
            out[k] = knot_speeds[0, k]
        return
    last = knot_count - 1
    if time_s >= knot_times[last]:
        for k in range(3):
            out[k] = knot_speeds[last, k]
        return
    i = 0
    while knot_times[i + 1] <= time_s:
        i += 1
    fraction = (time_s - knot_times[i]) / (knot_times[i + 1] - knot_times[i])
    for k in range(3):
        out[k] = knot_speeds[i, k] + fraction * (knot_speeds[i + 1, k] - knot_speeds[i, k])


def rotation_until(time_s: float, knot_times: Array, knot_speeds: Array, knot_count: int,
                   out: Array) -> None:
    """Rotation of each wheel from time 0 to ``time_s``: the trapezoid rule over the knots,
    exact for piecewise-linear speeds."""
    for k in range(3):
        out[k] = 0.0
    if time_s <= 0.0:
        return
    previous = np.empty(3)
    current = np.empty(3)
    speeds_at(0.0, knot_times, knot_speeds, knot_count, previous)
    previous_time = 0.0
    for i in range(knot_count + 1):
        if i < knot_count:
            t = knot_times[i]
            if t <= 0.0 or t >= time_s:
                continue
        else:
            t = time_s
        speeds_at(t, knot_times, knot_speeds, knot_count, current)
        for k in range(3):
            out[k] += 0.5 * (previous[k] + current[k]) * (t - previous_time)
            previous[k] = current[k]
        previous_time = t


def steering_at(time_s: float, steer_knots: Array, steer_count: int, out: Array) -> None:
    """Steering angle ``out[0]`` and rate ``out[1]`` at ``time_s`` from steering knots, rows
    ``[t_start, angle, rate, acceleration]``: quadratic from each row's start, the last holds."""
    i = 0
    while i + 1 < steer_count and steer_knots[i + 1, 0] <= time_s:
        i += 1
    if i == steer_count - 1:
        out[0] = steer_knots[i, 1]
        out[1] = 0.0
        return
    elapsed = max(0.0, time_s - steer_knots[i, 0])
    out[0] = steer_knots[i, 1] + steer_knots[i, 2] * elapsed \
        + 0.5 * steer_knots[i, 3] * elapsed * elapsed
    out[1] = steer_knots[i, 2] + steer_knots[i, 3] * elapsed
