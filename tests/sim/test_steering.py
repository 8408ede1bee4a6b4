"""The steering motion (docs/model.md, eqs. S1-S4): oracle, limits, invariants, backlash."""

import math

import numpy as np
import pytest

from omni_micro_sim import RobotParameters, SlipSimulator, kernels, simulate_open_loop
from omni_micro_sim.errors import ParameterError
from omni_micro_sim.open_loop import steering_motion
from omni_micro_sim.parameters import STEERING_PRESETS, SteeringParameters
from omni_micro_sim.reference import solve_ivp_reference
from omni_micro_sim.simulator import STANDING, wheel_headings_rad
from omni_micro_sim.steering import plan_steering

REALISTIC = STEERING_PRESETS['realistic']
# No offsets, no cantilever, centred mass: nothing but the steering can turn it.
SYMMETRIC = RobotParameters(cantilever_offset_m=0.0, steering=REALISTIC)


def literal_steering_terms(params, state, wheel_speeds, steering, steer_rate):
    """Eqs. S2-S4 as docs/model.md writes them: normal forces from the statics of the three
    contacts (solved as a linear system) and each contact's pivot moment."""
    _, _, phi, vx, vy, omega = state
    weight = params.mass_kg * params.gravity_m_s2
    positions = [params.wheel_distance_m * np.array(
        [math.cos(params.wheel1_angle_rad + k * 2 * math.pi / 3),
         math.sin(params.wheel1_angle_rad + k * 2 * math.pi / 3)]) for k in range(3)]
    statics = np.array([[1.0, 1.0, 1.0], [p[0] for p in positions], [p[1] for p in positions]])
    normal = np.linalg.solve(statics, weight * np.array([1.0, *params.center_of_mass_m]))
    rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
    a = params.steering.contact_radius_m
    moments = []
    for k in range(3):
        heading = steering + params.wheel_offsets_rad[k]
        w = rot @ np.array([math.cos(heading), math.sin(heading)])
        t = np.array([-w[1], w[0]])
        lever = rot @ positions[k]
        contact = np.array([vx, vy]) + omega * np.array([-lever[1], lever[0]]) \
            - params.wheel_radius_m * wheel_speeds[k] * w
        slip = math.hypot(contact @ w, contact @ t)
        rolling = abs(params.wheel_radius_m * wheel_speeds[k])
        spin = a * (omega + steer_rate)
        combined = math.sqrt(spin ** 2 + slip ** 2 + rolling ** 2)
        mu = params.mu_transverse * 2 / math.pi * math.atan(
            params.friction_steepness_s_m * combined)
        moments.append(-params.steering.pivot_coefficient * a * normal[k] * mu * spin / combined)
    return normal, np.array(moments)


@pytest.mark.parametrize('seed', range(5))
def test_kernel_matches_literal_steering_terms(seed):
    rng = np.random.default_rng(seed)
    params = RobotParameters(
        wheel_offsets_rad=tuple(rng.uniform(-0.1, 0.1, 3)), wheel1_angle_rad=rng.uniform(-3, 3),
        center_of_mass_m=tuple(rng.uniform(-1e-3, 1e-3, 2)),
        steering=REALISTIC.replace(contact_radius_m=rng.uniform(1e-5, 2e-4)))
    state = np.concatenate([rng.uniform(-0.05, 0.05, 2), rng.uniform(-3, 3, 1),
                            rng.uniform(-2e-4, 2e-4, 2), rng.uniform(-0.2, 0.2, 1)])
    speeds = rng.uniform(-0.1, 0.1, 3)
    steering, steer_rate = rng.uniform(-math.pi, math.pi), rng.uniform(-3, 3)
    kernel_params = params.as_kernel_array()
    geometry = kernels.wheel_geometry(wheel_headings_rad(params, steering), kernel_params)
    normal, moments = literal_steering_terms(params, state, speeds, steering, steer_rate)
    np.testing.assert_allclose(geometry[4], normal, rtol=1e-12)
    # The pivot moments are what the torque gains over the same contacts without a patch.
    with_patch, without = np.empty(6), np.empty(6)
    kernels.state_derivative(state, speeds, steer_rate, geometry, kernel_params, with_patch,
                             np.empty((4, 3)))
    point = params.replace(steering=params.steering.replace(contact_radius_m=0.0))
    kernels.state_derivative(state, speeds, steer_rate, geometry, point.as_kernel_array(),
                             without, np.empty((4, 3)))
    np.testing.assert_array_equal(with_patch[:5], without[:5])
    assert (with_patch[5] - without[5]) * params.moment_of_inertia_kg_m2 == pytest.approx(
        moments.sum(), rel=1e-9, abs=1e-22)


def test_centred_mass_loads_each_wheel_with_a_third_of_the_weight_exactly():
    params = RobotParameters()
    geometry = kernels.wheel_geometry(np.zeros(3), params.as_kernel_array())
    assert list(geometry[4]) == [params.mass_kg * params.gravity_m_s2 / 3.0] * 3


def test_point_contacts_give_no_pivot_torque():
    point = SYMMETRIC.replace(steering=REALISTIC.replace(contact_radius_m=0.0))
    result = simulate_open_loop(point, math.radians(90), 0.0, steer_from_rad=0.0)
    assert result.steering_time_s > 0.5
    assert result.final_state.as_array().tolist() == [0.0] * 6


def test_ideal_steering_is_the_paper_bit_for_bit():
    # Recorded before the steering motion existed (simulate --theta-deg 30 --duration 1
    # --xi-deg 1,2,-1): the default robot's numbers must not move in the last digit.
    robot = RobotParameters(wheel_offsets_rad=(math.radians(1), math.radians(2), math.radians(-1)))
    final = simulate_open_loop(robot, math.radians(30), 1.0).final_state
    assert (final.x_m * 1e3, final.y_m * 1e3) == (12.35647272360889, 7.3002478561313495)
    # Ideal steering from elsewhere is still instantaneous: the same move.
    assert simulate_open_loop(robot, math.radians(30), 1.0,
                              steer_from_rad=1.0).final_state == final


def test_symmetric_robot_turns_against_the_steering_by_the_creep_law():
    steer = math.radians(90)
    result = simulate_open_loop(SYMMETRIC, steer, 0.0, steer_from_rad=0.0)
    turned = result.final_state.phi_rad
    # Quasi-static balance of the three pivot moments (linear creep, eq. S2) against the
    # contacts' creep resisting the chassis' turn (eq. 10): kappa a^2 (omega + psi') = -L^2 omega.
    kappa_a2 = REALISTIC.pivot_coefficient * REALISTIC.contact_radius_m ** 2
    creep = kappa_a2 / (SYMMETRIC.wheel_distance_m ** 2 + kappa_a2)
    assert turned < 0.0   # against the steering
    assert -turned <= creep * abs(result.final_steering_rad) * 1.0001
    assert -turned >= 0.95 * creep * abs(result.final_steering_rad)   # atan barely saturates
    # The three contacts are alike, so their creep forces cancel and the centre stays put:
    # what is left is rounding (8e-15 m measured), far under a picometre.
    assert math.hypot(result.final_state.x_m, result.final_state.y_m) < 1e-12


def test_halving_the_step_changes_nothing():
    robot = RobotParameters(wheel_offsets_rad=(0.0, 0.05, 0.03), steering=REALISTIC,
                            center_of_mass_m=(3e-4, -1e-4))
    coarse = simulate_open_loop(robot, 1.2, 0.3, steer_from_rad=-0.4, max_step_s=2e-4)
    fine = simulate_open_loop(robot, 1.2, 0.3, steer_from_rad=-0.4, max_step_s=1e-4)
    assert np.abs(coarse.final_state.as_array()[:3] - fine.final_state.as_array()[:3]).max() \
        < 1e-11


def test_rk4_matches_the_solve_ivp_reference_through_a_steering_move():
    robot = RobotParameters(wheel_offsets_rad=(0.0, 0.05, 0.03), steering=REALISTIC,
                            center_of_mass_m=(3e-4, -1e-4))
    motion = steering_motion(robot, 1.2, -0.4)
    end = motion.duration_s + 0.2
    simulator = SlipSimulator(robot, steering_rad=-0.4)
    simulator.command_move(1.2, 0.1)
    simulator.step(end)
    profile = simulator.running_profile
    from omni_micro_sim.profile import move_profile

    reference, _ = solve_ivp_reference(robot, 1.2, move_profile(0.1), end, motion=motion)
    assert profile.end_time_s > motion.duration_s
    np.testing.assert_allclose(simulator.state.as_array()[:3], reference.as_array()[:3],
                               atol=1e-11)


def test_a_reversal_crosses_the_backlash_before_the_wheels_move():
    band = math.radians(2.0)
    steering = REALISTIC.replace(backlash_rad=band, step_rad=0.0)
    forward = plan_steering(steering, 0.0, 0.0, math.radians(20))
    # Centred at the start: half the band, then the wheels trail the gear by half the band.
    assert forward.final_wheel_rad == pytest.approx(math.radians(20) - band / 2, abs=1e-12)
    back = plan_steering(steering, forward.final_gear_rad, forward.final_wheel_rad, 0.0)
    first_move = back.wheel_knots[1, 0]
    assert back.wheel_at(first_move * 0.999)[0] == forward.final_wheel_rad
    gear_then = back.gear_at(first_move)[0]
    assert forward.final_gear_rad - gear_then == pytest.approx(band, abs=1e-12)
    assert back.final_wheel_rad == pytest.approx(band / 2, abs=1e-12)
    # Going on the same way again: no dead time.
    on = plan_steering(steering, back.final_gear_rad, back.final_wheel_rad, -0.1)
    assert on.wheel_at(1e-6)[1] != 0.0


def test_the_motor_limits_set_the_steering_time():
    steering = REALISTIC.replace(backlash_rad=0.0, step_rad=0.0)
    rate, accel = steering.rate_rad_s, steering.acceleration_rad_s2
    long = plan_steering(steering, 0.0, 0.0, 2.0)
    assert long.duration_s == pytest.approx(2.0 / rate + rate / accel, rel=1e-12)
    short = plan_steering(steering, 0.0, 0.0, 0.1)
    assert short.duration_s == pytest.approx(2 * math.sqrt(0.1 / accel), rel=1e-12)
    times = np.linspace(0, long.duration_s, 401)
    rates = np.array([long.wheel_at(t)[1] for t in times])
    assert rates.max() <= rate * (1 + 1e-12)
    # The short way round, on whole motor steps.
    stepped = REALISTIC.replace(backlash_rad=0.0)
    turn = plan_steering(stepped, math.radians(170), math.radians(170), math.radians(-170))
    assert turn.final_wheel_rad == pytest.approx(math.radians(190), abs=stepped.step_rad)
    assert turn.final_gear_rad / stepped.step_rad == pytest.approx(
        round(turn.final_gear_rad / stepped.step_rad), abs=1e-9)


def test_a_steering_only_move_keeps_the_wheels_still():
    simulator = SlipSimulator(SYMMETRIC)
    simulator.command(math.radians(45), STANDING)
    simulator.step(0.2)
    assert simulator.steering_rate_rad_s != 0.0
    assert simulator.wheel_speeds().tolist() == [0.0, 0.0, 0.0]
    simulator.step(1.0)
    assert simulator.steering_rate_rad_s == 0.0
    assert simulator.steering_rad == pytest.approx(
        math.radians(45) - REALISTIC.backlash_rad / 2, abs=REALISTIC.step_rad)


@pytest.mark.parametrize('changes', [
    {'backlash_rad': -0.01}, {'backlash_rad': float('nan')}, {'motor_speed_rad_s': 0.0},
    {'contact_radius_m': float('inf')}, {'pivot_coefficient': 1.5}, {'gear_ratio': -3},
    {'instantaneous': 'yes'}])
def test_bad_steering_parameters_are_refused_by_name(changes):
    name = next(iter(changes))
    with pytest.raises(ParameterError, match=f'steering.{name}'):
        SteeringParameters().replace(**changes)


def test_a_centre_of_mass_outside_the_wheels_is_refused():
    with pytest.raises(ParameterError, match='center_of_mass_m'):
        RobotParameters(center_of_mass_m=(3e-3, 0.0))
