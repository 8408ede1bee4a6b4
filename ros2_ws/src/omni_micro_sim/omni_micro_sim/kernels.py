"""Eqs. 1-13 of the paper as numba kernels: slip, friction, cantilever torque, rigid-body motion;
and the steering motion the paper leaves to future work (eqs. S1-S4 of docs/model.md).

State vector (inertial frame, SI): ``[x, y, phi, vx, vy, omega]``. Wheel k (k = 0, 1, 2 here for
the paper's wheels 1, 2, 3) sits at body angle ``wheel1_angle + k*120 deg`` at distance L and rolls
along the body-frame heading psi(t) + xi_k, where psi(t) is the wheels' common steering angle.
psi(t) is given as steering knots, rows ``[t_start, angle, rate, acceleration]`` (quadratic in
time from each row's start; the last row holds): one row for the paper's instantaneous steering,
several for a steering motion (:mod:`omni_micro_sim.steering` plans them).

These functions are the one definition of the physics; :mod:`omni_micro_sim.integrator` steps
them through time. Their ``.py_func`` attributes are the same code in plain Python, which the
benchmark uses as the pure-Python right-hand side.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import numpy.typing as npt

from omni_micro_sim.parameters import KERNEL_INDEX

# For mypy only: numba types the kernels itself, from the arrays it is called with.
Array = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

STATE_SIZE = 6
_M = KERNEL_INDEX['mass_kg']
_G = KERNEL_INDEX['gravity_m_s2']
_MU_L = KERNEL_INDEX['mu_longitudinal']
_MU_T = KERNEL_INDEX['mu_transverse']
_P = KERNEL_INDEX['friction_steepness_s_m']
_L = KERNEL_INDEX['wheel_distance_m']
_R = KERNEL_INDEX['wheel_radius_m']
_D1 = KERNEL_INDEX['signed_cantilever_offset_m']
_I = KERNEL_INDEX['moment_of_inertia_kg_m2']
_BETA1 = KERNEL_INDEX['wheel1_angle_rad']
_DRIVE1 = KERNEL_INDEX['wheel1_drive']
_COM_X = KERNEL_INDEX['center_of_mass_x_m']
_COM_Y = KERNEL_INDEX['center_of_mass_y_m']
_A = KERNEL_INDEX['contact_radius_m']
_PIVOT = KERNEL_INDEX['pivot_coefficient']
_TWO_OVER_PI = 2.0 / math.pi
_WHEEL_SPACING = 2.0 * math.pi / 3.0


@numba.njit(cache=True)
def friction_coefficient(mu: float, steepness: float, slip_speed: float) -> float:
    """Eq. 10: mu(Vs) = mu * 2/pi * atan(p*Vs)."""
    return mu * _TWO_OVER_PI * math.atan(steepness * slip_speed)


@numba.njit(cache=True)
def wheel_geometry(wheel_angles: Array, params: Array) -> Array:
    """Body-frame cos/sin of each wheel's position angle and rolling direction, and each wheel's
    normal force: a (5, 3) array.

    They stay fixed while the wheels do not steer, so the right-hand side only rotates them by
    phi. The normal forces are m*g/3 each (eq. 11) with the centre of mass at the centre, else
    from statics (eq. S4): N_k = m*g*(1/3 + 2/3 * (c . u_k)/L), u_k the unit vector to wheel k.
    """
    geometry = np.empty((5, 3))
    weight = params[_M] * params[_G]
    centred = params[_COM_X] == 0.0 and params[_COM_Y] == 0.0
    for k in range(3):
        position_angle = params[_BETA1] + k * _WHEEL_SPACING
        geometry[0, k] = math.cos(position_angle)
        geometry[1, k] = math.sin(position_angle)
        geometry[2, k] = math.cos(wheel_angles[k])
        geometry[3, k] = math.sin(wheel_angles[k])
        if centred:
            geometry[4, k] = weight / 3.0
        else:
            along = params[_COM_X] * geometry[0, k] + params[_COM_Y] * geometry[1, k]
            geometry[4, k] = weight * (1.0 / 3.0 + 2.0 / 3.0 * along / params[_L])
    return geometry


@numba.njit(cache=True)
def pivot_torque(normal_load: float, spin_rad_s: float, slip_speed: float,
                 rolling_speed: float, params: Array) -> float:
    """Eq. S2: the ground's pivot (spin) friction moment on one wheel's contact patch (N m).

    Full slip gives pivot_coefficient * mu_T * a * N against the spin; below it, the same
    regularised law as eq. 10 on the patch's combined speed, of which the spin's share
    (a*spin) sets the moment: sliding and rolling both take the moment down.
    """
    radius = params[_A]
    spin_speed = radius * spin_rad_s
    combined = math.sqrt(spin_speed * spin_speed + slip_speed * slip_speed
                         + rolling_speed * rolling_speed)
    if combined == 0.0:
        return 0.0
    full = params[_PIVOT] * radius * normal_load
    return float(-full * friction_coefficient(params[_MU_T], params[_P], combined)
                 * spin_speed / combined)


@numba.njit(cache=True)
def contact_terms(state: Array, wheel_speeds: Array, steer_rate: float, geometry: Array,
                  params: Array, slip_long: Array, slip_trans: Array, force_x: Array,
                  force_y: Array) -> float:
    """Slip velocities (eqs. 3-9) and friction forces (eq. 11) of the three contacts.

    ``geometry`` comes from :func:`wheel_geometry`; ``steer_rate`` is d(psi)/dt (rad/s).
    Fills ``slip_long``/``slip_trans`` (m/s, along W_k and T_k) and the inertial friction force
    components ``force_x``/``force_y`` (N). Returns the torque about the centre of mass (N m),
    including the cantilever torque of wheel 1 (eq. 12) and, with a contact radius, the pivot
    moments (eq. S2), i.e. the right-hand side of eq. 13.
    """
    cos_phi = math.cos(state[2])
    sin_phi = math.sin(state[2])
    vx = state[3]
    vy = state[4]
    omega = state[5]
    length = params[_L]
    radius = params[_R]
    steepness = params[_P]
    pivots = params[_A] > 0.0
    torque = 0.0
    for k in range(3):
        normal_load = geometry[4, k]
        # Eqs. 6-7: body-frame vectors rotated into the inertial frame.
        lever_x = length * (geometry[0, k] * cos_phi - geometry[1, k] * sin_phi)
        lever_y = length * (geometry[1, k] * cos_phi + geometry[0, k] * sin_phi)
        w_x = geometry[2, k] * cos_phi - geometry[3, k] * sin_phi
        w_y = geometry[3, k] * cos_phi + geometry[2, k] * sin_phi
        t_x = -w_y
        t_y = w_x
        # Eq. 3: contact velocity = body translation + omega x L_k + wheel spin (-r*omega_k*W_k).
        contact_x = vx - omega * lever_y - radius * wheel_speeds[k] * w_x
        contact_y = vy + omega * lever_x - radius * wheel_speeds[k] * w_y
        v_long = contact_x * w_x + contact_y * w_y
        v_trans = contact_x * t_x + contact_y * t_y
        f_long = -normal_load * friction_coefficient(params[_MU_L], steepness, v_long)
        f_trans = -normal_load * friction_coefficient(params[_MU_T], steepness, v_trans)
        rolling_speed = abs(radius * wheel_speeds[k])
        if k == 0 and params[_DRIVE1] == 0.0:
            # A passive wheel rolls freely: no longitudinal slip, no longitudinal force.
            rolling_speed = abs(v_long + radius * wheel_speeds[k])
            v_long = 0.0
            f_long = 0.0
        slip_long[k] = v_long
        slip_trans[k] = v_trans
        fx = f_long * w_x + f_trans * t_x
        fy = f_long * w_y + f_trans * t_y
        force_x[k] = fx
        force_y[k] = fy
        torque += lever_x * fy - lever_y * fx
        if k == 0:
            # Eq. 12: T_a = d1 x F1, d1 along wheel 1's axle (it steers with the wheel).
            d1 = params[_D1]
            torque += d1 * t_x * fy - d1 * t_y * fx
        if pivots:
            # The patch turns with the chassis and with the steering.
            torque += pivot_torque(normal_load, omega + steer_rate, math.hypot(v_long, v_trans),
                                   rolling_speed, params)
    return torque


@numba.njit(cache=True)
def state_derivative(state: Array, wheel_speeds: Array, steer_rate: float, geometry: Array,
                     params: Array, out: Array, scratch: Array) -> None:
    """Eq. 13: fills ``out`` with d(state)/dt. ``scratch`` is a (4, 3) work array."""
    force_x = scratch[2]
    force_y = scratch[3]
    torque = contact_terms(state, wheel_speeds, steer_rate, geometry, params, scratch[0],
                           scratch[1], force_x, force_y)
    mass = params[_M]
    out[0] = state[3]
    out[1] = state[4]
    out[2] = state[5]
    out[3] = (force_x[0] + force_x[1] + force_x[2]) / mass
    out[4] = (force_y[0] + force_y[1] + force_y[2]) / mass
    out[5] = torque / params[_I]


