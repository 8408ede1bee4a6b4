"""The servo mode: the filter over the slip core, the wheel profiles it rolls on, and what it
reaches in the twin against the paper's Fig. 11 goal."""

import math

import numpy as np
import pytest

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import Outcome
from omni_micro_control.observations import Observation
from omni_micro_control.servo import profile_to
from omni_micro_control.servo_config import ServoConfig
from omni_micro_control.slip_filter import SlipFilter
from omni_micro_sim.parameters import MotorLimits, RobotParameters, steering_preset
from omni_micro_sim.profile import move_profile
from omni_micro_sim.simulator import SlipSimulator
from omni_micro_studies.twin import run_servo

FIG11_ROBOT = RobotParameters(wheel_offsets_rad=(0.0, math.radians(3.0), math.radians(2.0)))
MACRO = CaptureUncertainty(8.6e-6, 10.8e-6, 4.3e-3)


@pytest.fixture(scope='module')
def fig11():
    return run_servo((0.1, 0.0), robot=FIG11_ROBOT, seed=0, config=ServoConfig(tolerance_m=0.5e-6))


def test_fig11_goal_within_half_a_micrometre_in_eight_seconds_and_one_stop(fig11):
    """The issue's target: (0, 0) -> (100, 0) mm, seed 0, ideal steering: within 0.5 um in at
    most 8.0 s of simulated time (the model mode needs 9.45 s, the move alone 7 s), one stop."""
    assert fig11.outcome is Outcome.REACHED
    assert fig11.deviation_m < 0.5e-6
    assert fig11.sim_time_s <= 8.0
    assert fig11.periods == 1 and fig11.stops == 1
    # It corrected the move while rolling, from the captures in motion.
    assert fig11.replans > 20 and fig11.captures_in_motion > 200


def test_the_filter_learns_the_offsets_the_servo_was_not_told(fig11):
    xi2, xi3 = fig11.offsets_rad
    assert math.degrees(xi2) == pytest.approx(3.0, abs=0.05)
    assert math.degrees(xi3) == pytest.approx(2.0, abs=0.05)


def test_the_filter_alone_tracks_an_open_loop_move_from_macro_captures():
    """Noisy macro captures every 33 ms of a robot the filter believes nominal: its pose ends
    within a few macro sigmas of the truth, and its offsets move from 0 to near the true ones."""
    profile = move_profile(3.0, MotorLimits())
    truth = SlipSimulator(FIG11_ROBOT)
    rng = np.random.default_rng(1)
    tracker = SlipFilter(RobotParameters(), Observation(0.0, 0.0, 0.0, 0.0, 'macro', MACRO), 0.0)
    tracker.command(0.0, 0.0, profile)
    truth.command(0.0, profile)
    errors = []
    for frame in range(1, 120):
        truth.step(1.0 / 30.0)
        real = truth.state
        noisy = (real.x_m + rng.normal(0, MACRO.x_sigma_m),
                 real.y_m + rng.normal(0, MACRO.y_sigma_m),
                 real.phi_rad + rng.normal(0, MACRO.heading_sigma_rad))
        assert tracker.update(Observation(frame / 30.0, *noisy, 'macro', MACRO))
        guess = tracker.state_at(frame / 30.0)
        errors.append(math.hypot(guess.x_m - real.x_m, guess.y_m - real.y_m))
    assert max(errors[-30:]) < 3 * MACRO.y_sigma_m
    xi2, xi3 = tracker.offsets_rad
    assert math.degrees(xi2) == pytest.approx(3.0, abs=0.5)
    assert math.degrees(xi3) == pytest.approx(2.0, abs=0.5)
    # A capture older than what the filter has taken in is left out, and says so.
    assert not tracker.update(Observation(1.0, 0.0, 0.0, 0.0, 'macro', MACRO))
    assert tracker.skipped == 1


@pytest.mark.parametrize('speed, rotation', [(0.0, 60.0), (8.0, 60.0), (8.0, 0.5), (0.3, 0.05),
                                             (0.0, 0.01), (8.7, 0.0)])
def test_a_profile_turns_the_wheels_as_far_as_asked_within_the_motor_limits(speed, rotation):
    limits = MotorLimits()
    profile = profile_to(speed, rotation, limits, 0.5, 0.12)
    profile.check_limits(limits)
    assert profile.speeds_at(0.0)[1] == pytest.approx(speed)
    assert profile.ends_at_rest
    stopping = speed * speed / (2.0 * limits.deceleration_rad_s2)
    # As far as asked, unless the wheels cannot stop that soon (then as soon as they can).
    assert profile.rotation_rad()[1] == pytest.approx(max(rotation, stopping), rel=1e-9,
                                                      abs=1e-9)


@pytest.mark.parametrize('name, value', [('tolerance_m', 0.0), ('crawl_speed_rad_s', math.nan),
                                         ('command_lead_s', -1.0), ('max_moves', 0),
                                         ('captures_per_stop', True)])
def test_a_bad_setting_is_named(name, value):
    with pytest.raises(ControllerConfigError, match=name):
        ServoConfig(**{name: value})


def test_with_a_steering_mechanism_it_steers_only_from_rest(monkeypatch):
    """--steering realistic stops the wheels to steer: every command sent while rolling keeps
    the angle of the command that runs."""
    from omni_micro_control.servo import ServoController

    preset = steering_preset('realistic')
    robot = RobotParameters(wheel_offsets_rad=(0.0, math.radians(1.0), math.radians(-1.0)),
                            steering=preset)
    replanned = []
    original = ServoController.on_capture_in_motion

    def watched(self, seen):
        before = self.command.steering_rad if self.command is not None else None
        command = original(self, seen)
        if command is not None:
            replanned.append((before, command.steering_rad))
        return command

    monkeypatch.setattr(ServoController, 'on_capture_in_motion', watched)
    run_servo((0.02, 0.0), robot=robot, seed=3, model_robot=RobotParameters(steering=preset),
              config=ServoConfig(max_moves=2), max_sim_time_s=30.0)
    assert len(replanned) > 3
    assert all(before == after for before, after in replanned)
