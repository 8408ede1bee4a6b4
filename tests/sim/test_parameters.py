import math

import pytest

from omni_micro_sim import CommandError, MotorLimits, ParameterError, RobotParameters, move_profile
from omni_micro_sim.parameters import STEERING_PRESETS


def test_defaults_are_the_papers_robot():
    params = RobotParameters()
    assert params.mass_kg == pytest.approx(2.8e-3)
    assert params.mu_longitudinal == params.mu_transverse == pytest.approx(0.21)
    assert params.friction_steepness_s_m == 1000.0
    assert params.wheel_distance_m == pytest.approx(4.15e-3)
    assert params.wheel_radius_m == pytest.approx(1.65e-3)
    assert params.cantilever_offset_m == pytest.approx(1e-3)
    assert params.moment_of_inertia_kg_m2 == pytest.approx(0.5 * 2.8e-3 * 4.5e-3 ** 2)


@pytest.mark.parametrize('name, value', [
    ('mass_kg', -1.0), ('mass_kg', float('nan')), ('mass_kg', 0.0),
    ('mu_longitudinal', -0.1), ('mu_transverse', float('inf')),
    ('friction_steepness_s_m', 0.0), ('friction_steepness_s_m', -5.0),
    ('wheel_radius_m', 'abc'), ('chassis_radius_m', 0.0), ('cantilever_offset_m', -1e-3),
    ('wheel1_angle_rad', float('nan')),
])
def test_bad_parameter_is_named(name, value):
    with pytest.raises(ParameterError, match=name):
        RobotParameters().replace(**{name: value})


def test_bad_offsets_and_unknown_names_are_rejected():
    with pytest.raises(ParameterError, match='wheel_offsets_rad'):
        RobotParameters(wheel_offsets_rad=(0.0, 0.1))  # type: ignore[arg-type]  # on purpose
    with pytest.raises(ParameterError, match=r'wheel_offsets_rad\[2\]'):
        RobotParameters(wheel_offsets_rad=(0.0, 0.1, float('nan')))
    with pytest.raises(ParameterError, match='wheel_count'):
        RobotParameters().replace(wheel_count=4)
    with pytest.raises(ParameterError, match='cantilever_side'):
        RobotParameters(cantilever_side='up')  # type: ignore[arg-type]  # a user's YAML string


@pytest.mark.parametrize('duration', [0.0, -1.0, float('nan'), float('inf'), 'x'])
def test_bad_move_duration_is_named(duration):
    with pytest.raises(CommandError, match='duration'):
        move_profile(duration)


@pytest.mark.parametrize('duration', [0.01, 0.05, 0.174, 0.2, 1.0, 7.0])
def test_profile_turns_the_wheels_by_cruise_speed_times_duration(duration):
    limits = MotorLimits()
    profile = move_profile(duration, limits)
    assert profile.rotation_rad() == pytest.approx([8.7 * duration] * 3, rel=1e-12)
    peak = profile.knot_speeds_rad_s.max()
    assert peak <= 8.7 + 1e-12
    # Slopes never exceed the motors' acceleration.
    slopes = abs(profile.knot_speeds_rad_s[1:, 0] - profile.knot_speeds_rad_s[:-1, 0]) / \
        abs(profile.knot_times_s[1:] - profile.knot_times_s[:-1])
    assert max(slopes) == pytest.approx(50.0, rel=1e-9) or max(slopes) < 50.0
    if duration < 8.7 / 50.0:
        assert profile.knot_times_s.size == 3 and peak < 8.7   # triangle
    assert math.isclose(profile.end_time_s, duration + 0.174) or duration < 0.174


def test_finite_values_whose_inertia_overflows_are_refused():
    # Found by the property test: R = 1e200 m is finite, m R^2 / 2 is not.
    with pytest.raises(ParameterError, match='moment of inertia'):
        RobotParameters(chassis_radius_m=1e200)


@pytest.mark.parametrize(('name', 'value'), [('gear_ratio', 1.0e300),
                                             ('motor_speed_rad_s', 1.0e-300),
                                             ('motor_speed_rad_s', 1.0e300),
                                             ('motor_acceleration_rad_s2', 1.0e-9)])
def test_steering_the_model_cannot_integrate_is_refused_at_the_start(name, value):
    """A half turn of the wheels beyond a minute (1e299 s with a 1e300 gear ratio) is refused
    where the values are defined, so no node or planner meets it mid-run."""
    with pytest.raises(ParameterError, match=r'steering: a half turn of the wheels would take '
                                             r'[0-9.e+]+ s with .* at most 60 s'):
        STEERING_PRESETS['realistic'].replace(**{name: value})
    slow_but_fine = STEERING_PRESETS['realistic'].replace(gear_ratio=100.0)
    assert math.pi / slow_but_fine.rate_rad_s < 60.0


def test_a_contact_patch_wider_than_the_wheel_is_refused():
    steering = STEERING_PRESETS['realistic'].replace(contact_radius_m=1.0)
    with pytest.raises(ParameterError, match=r'steering.contact_radius_m must be below the '
                                             r'wheel radius 0.00165 m, got 1.0'):
        RobotParameters(steering=steering)
