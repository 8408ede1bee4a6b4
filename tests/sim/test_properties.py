"""Property-based: whatever parameters and commands it is given, the slip core either steps to a
finite state or raises an error that says what was wrong; it never returns NaN silently."""

import math

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from omni_micro_sim.errors import CommandError, ParameterError, SimulationError
from omni_micro_sim.parameters import MotorLimits, RobotParameters
from omni_micro_sim.profile import WheelSpeedProfile
from omni_micro_sim.simulator import SlipSimulator

ANY_FLOAT = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.floats(min_value=-1e3, max_value=1e3),
)


def around(value: float) -> st.SearchStrategy:
    """Mostly plausible values near the paper's, sometimes anything at all."""
    return st.one_of(st.floats(min_value=value * 0.1, max_value=value * 10.0), ANY_FLOAT)


robots = st.fixed_dictionaries({
    'mass_kg': around(2.8e-3),
    'mu_longitudinal': around(0.21),
    'mu_transverse': around(0.21),
    'friction_steepness_s_m': around(1000.0),
    'wheel_radius_m': around(1.65e-3),
    'cantilever_offset_m': around(1e-3),
    'chassis_radius_m': around(4.5e-3),
    'wheel_offsets_rad': st.tuples(around(0.05), around(0.05), around(0.05)),
})

profiles = st.tuples(
    st.lists(ANY_FLOAT, min_size=1, max_size=5),                        # knot times
    st.lists(st.one_of(st.floats(min_value=-8.7, max_value=8.7), ANY_FLOAT),
             min_size=1, max_size=15),                                  # speeds
)


def build_profile(times, speeds):
    count = len(times)
    values = (speeds * (3 * count))[:3 * count]
    return WheelSpeedProfile(np.array(times), np.array(values).reshape(count, 3))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(robot=robots, profile=profiles, steering=ANY_FLOAT,
       steps=st.lists(st.one_of(st.floats(min_value=1e-4, max_value=0.05), ANY_FLOAT),
                      min_size=1, max_size=4))
def test_the_core_steps_to_a_finite_state_or_raises(robot, profile, steering, steps):
    try:
        params = RobotParameters(**robot)
    except ParameterError as error:
        assert str(error)   # names the value
        return
    simulator = SlipSimulator(params)
    try:
        simulator.command(steering, build_profile(*profile), MotorLimits())
    except (CommandError, ParameterError) as error:
        assert str(error)
        return
    for dt in steps:
        before = simulator.state
        try:
            state = simulator.step(dt)
        except CommandError as error:
            assert not (math.isfinite(dt) and dt > 0)
            assert str(error)
            continue
        except SimulationError as error:
            assert 'non-finite' in str(error)
            assert simulator.state == before   # the state is left as it was
            continue
        assert all(math.isfinite(v) for v in state.as_array())


knot_profiles = st.integers(min_value=1, max_value=6).flatmap(lambda count: st.tuples(
    st.lists(st.floats(min_value=0.001, max_value=0.5), min_size=count, max_size=count),
    st.lists(st.floats(min_value=-8.7, max_value=8.7), min_size=3 * count,
             max_size=3 * count)))


@settings(max_examples=200, deadline=None)
@given(knot_profiles, st.floats(min_value=-0.1, max_value=3.0))
def test_profile_speeds_and_rotation_are_the_piecewise_linear_ones(profile, time_s):
    gaps, speeds = profile
    times = np.cumsum(gaps)
    knots = WheelSpeedProfile(times, np.reshape(speeds, (len(gaps), 3)))
    # numpy's own interpolation and trapezoid rule on a grid holding every knot are the truth.
    expected_speeds = [np.interp(time_s, times, knots.knot_speeds_rad_s[:, k]) for k in range(3)]
    assert np.allclose(knots.speeds_at(time_s), expected_speeds, rtol=1e-12, atol=1e-12)
    grid = np.union1d(np.linspace(0.0, max(time_s, 0.0), 7),
                      times[(times > 0.0) & (times < time_s)])
    grid_speeds = np.array([[np.interp(t, times, knots.knot_speeds_rad_s[:, k])
                             for k in range(3)] for t in grid])
    expected_rotation = (np.trapezoid(grid_speeds, grid, axis=0) if time_s > 0.0
                         else np.zeros(3))
    assert np.allclose(knots.rotation_until(time_s), expected_rotation, rtol=1e-9, atol=1e-12)
