"""A reference solution with scipy's solve_ivp, for checking the RK4 integrator.

It integrates the same right-hand side (:func:`kernels.state_derivative`) with an adaptive
high-order or stiff solver, segment by segment between the profile's knots. With the environment
variable NUMBA_DISABLE_JIT=1 the right-hand side runs as plain Python (the benchmark's reference).
"""

from __future__ import annotations

import itertools

import numpy as np
from scipy.integrate import solve_ivp

from omni_micro_sim import integrator, kernels
from omni_micro_sim.errors import SimulationError
from omni_micro_sim.parameters import RobotParameters
from omni_micro_sim.profile import WheelSpeedProfile
from omni_micro_sim.simulator import delayed, wheel_headings_rad
from omni_micro_sim.state import RobotState
from omni_micro_sim.steering import SteeringMotion


def solve_ivp_reference(params: RobotParameters, steering_rad: float,
                        profile: WheelSpeedProfile, end_time_s: float, *,
                        start: RobotState | None = None, method: str = 'DOP853',
                        rtol: float = 1e-10, atol: float = 1e-14,
                        motion: SteeringMotion | None = None) -> tuple[RobotState, int]:
    """Integrate from rest (or ``start``) to ``end_time_s``; return the state and rhs calls.

    With ``motion`` the wheels first steer (the profile waits for it), their directions
    recomputed at every call.
    """
    kernel_params = params.as_kernel_array()
    geometry = kernels.wheel_geometry(wheel_headings_rad(params, steering_rad), kernel_params)
    if motion is not None:
        profile = delayed(profile, motion.duration_s)
    knot_times = profile.knot_times_s
    knot_speeds = profile.knot_speeds_rad_s
    knot_count = knot_times.size
    speeds = np.empty(3)
    scratch = np.empty((4, 3))
    calls = 0

    def rhs(time_s: float, state: np.ndarray) -> np.ndarray:
        nonlocal calls
        calls += 1
        out = np.empty(6)
        integrator.speeds_at(time_s, knot_times, knot_speeds, knot_count, speeds)
        rate = 0.0
        wheels = geometry
        if motion is not None:
            angle, rate = motion.wheel_at(time_s)
            wheels = kernels.wheel_geometry(wheel_headings_rad(params, angle), kernel_params)
        kernels.state_derivative(state, speeds, rate, wheels, kernel_params, out, scratch)
        return out

    steer_times = [] if motion is None else list(motion.wheel_knots[:, 0])
    breaks = sorted({t for t in [*knot_times, *steer_times] if 0.0 < t < end_time_s})
    edges = [0.0, *breaks, end_time_s]
    state = (start or RobotState()).as_array()
    for t0, t1 in itertools.pairwise(edges):
        solution = solve_ivp(rhs, (t0, t1), state, method=method, rtol=rtol, atol=atol)
        if not solution.success:
            raise SimulationError(f'reference solver {method} failed on [{t0}, {t1}] s: '
                                  f'{solution.message}')
        state = solution.y[:, -1]
    return RobotState.from_array(state), calls
