"""Physical invariants of eqs. 1-13 and an independent, literal transcription as an oracle."""

import math

import numpy as np
import pytest

from omni_micro_sim import RobotParameters, RobotState, SlipSimulator, kernels, simulate_open_loop
from omni_micro_sim.paper import FIG8
from omni_micro_sim.simulator import wheel_headings_rad


def literal_equations(params, state, wheel_speeds, steering):
    """Eqs. 3-13 as the paper writes them, with 3-vectors, rotation matrices, cross products."""
    _, _, phi, vx, vy, omega = state
    rot = np.array([[math.cos(phi), -math.sin(phi), 0], [math.sin(phi), math.cos(phi), 0],
                    [0, 0, 1]])
    v_r = np.array([vx, vy, 0.0])
    phi_dot = np.array([0.0, 0.0, omega])
    weight_share = params.mass_kg * params.gravity_m_s2 / 3
    forces = []
    torque = 0.0
    for k in range(3):
        beta = params.wheel1_angle_rad + k * 2 * math.pi / 3
        theta_k = steering + params.wheel_offsets_rad[k]
        l_m = params.wheel_distance_m * np.array([math.cos(beta), math.sin(beta), 0])
        w_m = np.array([math.cos(theta_k), math.sin(theta_k), 0])
        t_m = np.array([-math.sin(theta_k), math.cos(theta_k), 0])
        w_o, t_o, l_o = rot @ w_m, rot @ t_m, rot @ l_m
        wheel_rate = wheel_speeds[k] * np.cross([0, 0, 1], w_o)   # spin axis along the axle
        r_o = np.array([0, 0, -params.wheel_radius_m])
        v_s = v_r + np.cross(phi_dot, l_o) + np.cross(wheel_rate, r_o)          # eq. 3
        v_sl, v_st = v_s @ w_o, v_s @ t_o                                        # eqs. 4-5
        mu = lambda m, v: m * 2 / math.pi * math.atan(params.friction_steepness_s_m * v)  # noqa
        mu_l = mu(params.mu_longitudinal, v_sl) if (k or params.wheel1_active) else 0.0
        force = -weight_share * (mu_l * w_o + mu(params.mu_transverse, v_st) * t_o)  # eq. 11
        forces.append(force)
        torque += np.cross(l_o, force)[2]
        if k == 0:
            d1 = params.signed_cantilever_offset_m * t_o
            torque += np.cross(d1, force)[2]                                     # eq. 12
    total = np.sum(forces, axis=0)
    return np.array([vx, vy, omega, total[0] / params.mass_kg, total[1] / params.mass_kg,
                     torque / params.moment_of_inertia_kg_m2])                   # eq. 13


@pytest.mark.parametrize('wheel1_active', [True, False])
@pytest.mark.parametrize('seed', range(5))
def test_kernel_matches_literal_equations(seed, wheel1_active):
    rng = np.random.default_rng(seed)
    params = RobotParameters(wheel_offsets_rad=tuple(rng.uniform(-0.2, 0.2, 3)),
                             wheel1_active=wheel1_active, wheel1_angle_rad=rng.uniform(-3, 3))
    state = np.concatenate([rng.uniform(-0.05, 0.05, 2), rng.uniform(-3, 3, 1),
                            rng.uniform(-0.02, 0.02, 2), rng.uniform(-2, 2, 1)])
    speeds = rng.uniform(-8.7, 8.7, 3)
    steering = rng.uniform(-math.pi, math.pi)
    out = np.empty(6)
    kernel_params = params.as_kernel_array()
    geometry = kernels.wheel_geometry(wheel_headings_rad(params, steering), kernel_params)
    kernels.state_derivative(state, speeds, 0.0, geometry, kernel_params, out, np.empty((4, 3)))
    np.testing.assert_allclose(out, literal_equations(params, state, speeds, steering),
                               rtol=1e-10, atol=1e-12)


def test_friction_always_opposes_slip():
    rng = np.random.default_rng(7)
    params = RobotParameters(wheel_offsets_rad=(0.0, 0.05, 0.03))
    kernel_params = params.as_kernel_array()
    for _ in range(200):
        state = np.concatenate([[0, 0], rng.uniform(-3, 3, 1), rng.uniform(-0.02, 0.02, 2),
                                rng.uniform(-3, 3, 1)])
        slip_l, slip_t, fx, fy = (np.empty(3) for _ in range(4))
        angles = wheel_headings_rad(params, rng.uniform(-3, 3))
        kernels.contact_terms(state, rng.uniform(-9, 9, 3), 0.0,
                              kernels.wheel_geometry(angles, kernel_params), kernel_params,
                              slip_l, slip_t, fx, fy)
        for k in range(3):
            heading = angles[k] + state[2]
            w = np.array([math.cos(heading), math.sin(heading)])
            t = np.array([-w[1], w[0]])
            slip = slip_l[k] * w + slip_t[k] * t
            force = np.array([fx[k], fy[k]])
            assert force @ slip <= 0.0
            # Each component separately opposes its own slip (eq. 11).
            assert (force @ w) * slip_l[k] <= 0.0 and (force @ t) * slip_t[k] <= 0.0


@pytest.mark.parametrize('steering_deg', [0.0, 37.0, 135.0, -90.0])
def test_ideal_robot_goes_straight_without_turning(steering_deg):
    ideal = RobotParameters(cantilever_offset_m=0.0)
    result = simulate_open_loop(ideal, math.radians(steering_deg), 1.0)
    assert abs(result.final_state.phi_rad) < 1e-12
    heading = math.atan2(result.final_state.y_m, result.final_state.x_m)
    assert math.remainder(heading - math.radians(steering_deg), 2 * math.pi) == \
        pytest.approx(0.0, abs=1e-9)
    assert result.drift_m < 1e-9


def test_ramp_slip_settles_where_friction_gives_m_times_a():
    # Ideal robot, steering 0: during the +50 rad/s^2 ramp the body accelerates at r*50 and the
    # summed longitudinal friction must equal m*a.
    params = RobotParameters(cantilever_offset_m=0.0)
    simulator = SlipSimulator(params)
    simulator.command_move(0.0, 2.0)
    simulator.step(0.15)   # 0.15 s into the 0.174 s ramp: transients (~0.5 ms) long gone
    acceleration = params.wheel_radius_m * 50.0
    slip = simulator.slip().longitudinal_m_s
    share = params.mass_kg * params.gravity_m_s2 / 3
    friction = -share * params.mu_longitudinal * 2 / math.pi * np.arctan(
        params.friction_steepness_s_m * slip)
    assert np.sum(friction) == pytest.approx(params.mass_kg * acceleration, rel=1e-6)
    # The body lags the rolling speed by exactly that slip, the same at every wheel.
    np.testing.assert_allclose(slip, slip[0], rtol=1e-9)
    assert slip[0] < 0.0
    assert simulator.state.vx_m_s == pytest.approx(acceleration * 0.15 + slip[0], rel=1e-9)


def test_passive_wheel1_transmits_no_longitudinal_force():
    params = RobotParameters(wheel1_active=False, wheel_offsets_rad=(0.0, 0.05, 0.03))
    state = np.array([0.0, 0.0, 0.3, 0.01, -0.004, 0.5])
    slip_l, slip_t, fx, fy = (np.empty(3) for _ in range(4))
    angles = wheel_headings_rad(params, 0.4)
    kernel_params = params.as_kernel_array()
    kernels.contact_terms(state, np.full(3, 8.7), 0.0,
                          kernels.wheel_geometry(angles, kernel_params), kernel_params,
                          slip_l, slip_t, fx, fy)
    heading = angles[0] + state[2]
    assert fx[0] * math.cos(heading) + fy[0] * math.sin(heading) == pytest.approx(0.0, abs=1e-18)
    assert abs(fx[0]) + abs(fy[0]) > 0.0   # transverse friction remains


def test_halving_the_step_does_not_change_the_result():
    params = FIG8.robot()
    coarse = simulate_open_loop(params, 0.0, FIG8.duration_s, max_step_s=2e-4)
    fine = simulate_open_loop(params, 0.0, FIG8.duration_s, max_step_s=1e-4)
    assert math.hypot(coarse.final_state.x_m - fine.final_state.x_m,
                      coarse.final_state.y_m - fine.final_state.y_m) < 1e-10


def test_at_rest_stays_at_rest():
    simulator = SlipSimulator(RobotParameters(), RobotState(0.01, 0.02, 0.3))
    for _ in range(10):
        simulator.step(0.01)
    assert simulator.state == RobotState(0.01, 0.02, 0.3)


def test_stop_ramps_down_and_the_robot_comes_to_rest():
    simulator = SlipSimulator(RobotParameters())
    simulator.command_move(0.3, 2.0)
    simulator.step(1.0)
    rotation_before_stop = simulator.wheel_rotations_rad()
    assert rotation_before_stop == pytest.approx([8.7 * (1.0 - 0.087)] * 3, rel=1e-9)
    simulator.stop()
    assert simulator.status.value == 'moving'
    simulator.step(0.2)   # 8.7 rad/s ramps down in 0.174 s
    # The ramp-down adds the triangle 8.7 * 0.174 / 2 to the rotation.
    assert simulator.wheel_rotations_rad() == pytest.approx(
        rotation_before_stop + 8.7 * 0.174 / 2, rel=1e-9)
    for _ in range(100):
        if simulator.status.value == 'idle':
            break
        simulator.step(0.001)
    assert simulator.status.value == 'idle'
    assert simulator.state.speed_m_s < 1e-9


def test_passive_wheel1_reports_its_free_rolling_speed():
    simulator = SlipSimulator(RobotParameters(wheel1_active=False))
    simulator.command_move(0.0, 1.0)
    simulator.step(0.5)
    speeds = simulator.wheel_speeds()
    assert speeds[1] == speeds[2] == pytest.approx(8.7)
    # The body follows the two driven wheels and wheel 1 rolls along at their speed
    # (within the small slip of the driven wheels: ~1e-4 m/s / r ~ 0.06 rad/s).
    assert speeds[0] == pytest.approx(8.7, abs=0.1)
    assert simulator.slip().longitudinal_m_s[0] == 0.0
