"""Section 4.1 logic: angle modifier, distance comparator, end rule, timeouts, event order."""

import math
import re

import pytest

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import (
    Finished,
    Move,
    Outcome,
    Phase,
    VisionFeedbackController,
    wrap_angle,
)
from omni_micro_control.feedback_config import MODEL_CAPTURES_PER_STOP, FeedbackConfig
from omni_micro_control.move_watcher import MoveWatcher
from omni_micro_control.observations import Observation

GOAL = (0.1, 0.0)



def a_move(decision: Move | Finished | None) -> Move:
    assert isinstance(decision, Move), decision
    return decision


def an_end(decision: Move | Finished | None) -> Finished:
    assert isinstance(decision, Finished), decision
    return decision

def settled_controller(config: FeedbackConfig | None = None) -> VisionFeedbackController:
    controller = VisionFeedbackController(config)
    controller.set_goal(GOAL, stopped_at_s=0.0)
    return controller


def test_first_capture_after_timer2_decides_and_earlier_ones_do_not():
    controller = settled_controller()
    assert controller.on_capture(Observation(0.09, 0.0, 0.0, 0.0)) is None
    move = controller.on_capture(Observation(0.1, 0.0, 0.0, 0.0))
    assert isinstance(move, Move)
    assert move.start_s == pytest.approx(0.1 + controller.config.command_lead_s)


def test_angle_modifier_is_alpha_minus_phi_wrapped():
    controller = settled_controller()
    # Robot at (0.1, -0.01) facing +170 deg: goal straight up (alpha = 90 deg).
    move = a_move(controller.on_capture(Observation(0.2, 0.1, -0.01, math.radians(170.0))))
    assert math.degrees(move.steering_rad) == pytest.approx(-80.0)
    assert wrap_angle(math.radians(190.0)) == pytest.approx(math.radians(-170.0))
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)


@pytest.mark.parametrize('distance_m, expected_s', [
    (0.05, 0.2),                          # far: timer1 = 0.2 s
    (1.5e-3, 0.05),                       # within 2 mm: timer1 = 0.05 s
    (0.3e-3, 0.3e-3 / (1.65e-3 * 8.7)),   # shorter than one period: shortened to land on it
])
def test_distance_comparator_and_shortened_last_move(distance_m, expected_s):
    controller = settled_controller()
    move = a_move(controller.on_capture(Observation(0.2, GOAL[0] - distance_m, 0.0, 0.0)))
    assert move.duration_s == pytest.approx(expected_s)
    assert move.remaining_m == pytest.approx(distance_m)


def test_reached_within_tolerance_and_gave_up_after_max_periods():
    controller = settled_controller(FeedbackConfig(tolerance_m=3e-6))
    done = controller.on_capture(Observation(0.2, GOAL[0] - 2e-6, 0.0, 0.0, 'micro'))
    assert isinstance(done, Finished) and done.outcome is Outcome.REACHED
    assert controller.phase is Phase.DONE

    controller = settled_controller(FeedbackConfig(max_periods=1))
    assert isinstance(controller.on_capture(Observation(0.2, 0.0, 0.0, 0.0)), Move)
    controller.on_wheels_stopped(1.0)
    done = an_end(controller.on_capture(Observation(1.2, 0.05, 0.0, 0.0)))
    assert done.outcome is Outcome.GAVE_UP and done.periods == 1


def test_capture_that_overtakes_the_stop_report_is_kept_not_skipped():
    controller = settled_controller()
    controller.on_capture(Observation(0.2, 0.0, 0.0, 0.0))
    # The capture exposed after timer2 arrives before the wheel state that ends the move.
    early = Observation(1.15, 0.0028, 0.0, 0.0)
    assert controller.on_capture(early) is None
    move = controller.on_wheels_stopped(1.0)
    assert isinstance(move, Move) and move.observation == early


def test_timeout_tries_again_then_reports_lost():
    controller = settled_controller(FeedbackConfig(capture_timeout_s=0.5, max_capture_tries=3))
    assert controller.on_time(0.55) == (0, None)
    assert controller.on_time(0.65) == (1, None)
    tries, finished = controller.on_time(1.65)
    assert tries == 3 and an_end(finished).outcome is Outcome.LOST


@pytest.mark.parametrize('said', [None, 'soon', 'nan', '-0.5', 'inf'])
def test_an_age_that_is_none_changes_no_timeout(said):
    controller = settled_controller(FeedbackConfig(capture_timeout_s=0.5, max_capture_tries=3))
    assert controller.take_capture_age('macro', said) is None
    assert controller.on_time(0.65) == (1, None)


def test_timeouts_wait_as_much_longer_as_the_cameras_say_their_captures_come_late():
    """A driver whose captures come 1.7 s after their stamps (a slow host, a long cable): a
    capture stamped at timer2's end cannot come sooner, so the tries count from then, the
    oldest any camera stated; a later, younger statement shortens nothing."""
    controller = settled_controller(FeedbackConfig(capture_timeout_s=0.5, max_capture_tries=3))
    assert controller.take_capture_age('macro', '1.7') == pytest.approx(1.7)
    assert controller.take_capture_age('micro', '0.2') is None
    assert controller.take_capture_age('macro', '0.9') is None
    assert controller.on_time(0.1 + 1.7 + 0.45) == (0, None)
    assert controller.on_time(0.1 + 1.7 + 0.55) == (1, None)
    # Its capture, stamped after timer2, comes 2.5 s late and still decides.
    assert controller.on_capture(Observation(0.15, 0.05, 0.0, 0.0)) is not None
    late = settled_controller(FeedbackConfig(capture_timeout_s=0.5, max_capture_tries=3))
    late.take_capture_age('macro', '1.7')
    tries, finished = late.on_time(0.1 + 1.7 + 1.55)
    assert tries == 3 and an_end(finished).outcome is Outcome.LOST
    assert an_end(finished).reason == ('no capture within 3 x 0.5 s and the 1.700 s the cameras '
                                       'say their captures take after the robot stopped')


def test_open_loop_makes_one_move_then_completes():
    controller = settled_controller(FeedbackConfig(open_loop_duration_s=7.0))
    move = a_move(controller.on_capture(Observation(0.2, 0.0, 0.0, 0.0)))
    assert move.duration_s == 7.0
    controller.on_wheels_stopped(7.5)
    assert an_end(controller.on_capture(Observation(7.7, 0.09, 0.01, 0.0))).outcome is \
        Outcome.COMPLETED


def test_open_loop_to_the_goal_makes_the_nominal_robots_one_move_whatever_the_distance():
    """Each goal, as a fleet's open-loop robot gets its legs' ends: one move aimed from the
    capture, for the time the nominal robot takes over the distance (section 4.1's rule cuts
    it into timer1 periods), then completed wherever the robot stands, without feedback."""
    for goal_m in ((0.1, 0.0), (0.03, -0.04)):
        controller = VisionFeedbackController(FeedbackConfig(open_loop_to_goal=True))
        controller.set_goal(goal_m, stopped_at_s=0.0)
        move = a_move(controller.on_capture(Observation(0.2, 0.0, 0.0, math.pi / 2)))
        assert move.duration_s == pytest.approx(math.hypot(*goal_m) / controller.config.speed_m_s)
        assert move.steering_rad == pytest.approx(math.atan2(goal_m[1], goal_m[0]) - math.pi / 2)
        controller.on_wheels_stopped(move.start_s + move.duration_s)
        far_off = Observation(move.start_s + move.duration_s + 0.2, goal_m[0] - 0.002,
                              goal_m[1], 0.0)
        assert an_end(controller.on_capture(far_off)).outcome is Outcome.COMPLETED


def test_non_finite_capture_is_ignored():
    controller = settled_controller()
    assert controller.on_capture(Observation(0.2, math.nan, 0.0, 0.0)) is None
    assert controller.phase is Phase.SETTLING


@pytest.mark.parametrize('field, value', [
    ('far_period_s', -0.2), ('tolerance_m', math.nan), ('max_periods', 0),
    ('settle_wait_s', math.inf), ('max_capture_tries', 2.5)])
def test_bad_config_names_the_value(field, value):
    with pytest.raises(ControllerConfigError, match=field):
        FeedbackConfig(**{field: value})


def test_move_watcher_needs_the_rotation_and_a_standstill():
    watcher = MoveWatcher()
    watcher.on_wheel_state((0.0, 5.0, 5.0), (0.0, 0.0, 0.0))
    watcher.expect(1.74)
    assert not watcher.on_wheel_state((0.0, 5.0, 5.0), (0.0, 0.0, 0.0))   # not started yet
    assert not watcher.on_wheel_state((1.0, 6.0, 6.0), (8.7, 8.7, 8.7))   # turning
    assert watcher.on_wheel_state((1.74, 6.74, 6.74), (0.0, 0.0, 0.0))
    assert not watcher.on_wheel_state((1.74, 6.74, 6.74), (0.0, 0.0, 0.0))  # reported once


def test_move_watcher_waits_for_the_steering_to_stop_too():
    watcher = MoveWatcher()
    watcher.on_wheel_state((0.0, 5.0, 5.0), (0.0, 0.0, 0.0))
    watcher.expect(0.0)   # a steering-only move: no rotation to wait for
    assert not watcher.on_wheel_state((0.0, 5.0, 5.0), (0.0, 0.0, 0.0), 2.1)   # steering
    assert watcher.on_wheel_state((0.0, 5.0, 5.0), (0.0, 0.0, 0.0), 0.0)


def test_out_of_view_before_timer2_ends_is_lost_when_it_ends():
    controller = settled_controller()
    assert controller.on_out_of_field(0.04) is None
    assert controller.on_time(0.08) == (0, None)
    _, finished = controller.on_time(0.1)
    assert finished is not None
    assert finished.outcome is Outcome.LOST and 'outside' in finished.reason


def test_a_move_whose_end_is_never_reported_ends_lost():
    controller = settled_controller()
    move = a_move(controller.on_capture(Observation(0.2, 0.0, 0.0, 0.0)))
    assert controller.on_time(move.start_s + 1.0) == (0, None)
    _, finished = controller.on_time(move.start_s + 10.0)
    assert finished is not None
    assert finished.outcome is Outcome.LOST and 'end of the move' in finished.reason


def test_a_new_goal_during_a_move_waits_for_its_end():
    controller = settled_controller()
    controller.on_capture(Observation(0.2, 0.0, 0.0, 0.0))
    replaced = controller.set_goal((0.05, 0.0), stopped_at_s=0.3)
    assert an_end(replaced).outcome is Outcome.CANCELLED and controller.phase is Phase.MOVING
    controller.on_wheels_stopped(0.6)
    assert controller.deadline_s == pytest.approx(0.7)
    assert isinstance(controller.on_capture(Observation(0.71, 0.003, 0.0, 0.0)), Move)


def test_a_late_started_controller_counts_timer2_from_the_robots_clock():
    on_time = settled_controller()
    on_time.restart_wait(0.02)          # first wheel state of a normal start: no change
    assert on_time.deadline_s == pytest.approx(0.1)
    late = settled_controller()
    late.restart_wait(7.5)              # respawned into a running graph
    assert late.deadline_s == pytest.approx(7.6)
    assert late.on_time(7.7) == (0, None)


# -- honest outcomes: the capture's uncertainty counts ---------------------------------------
MICRO = CaptureUncertainty(0.115e-6, 0.144e-6, 6e-5)     # 95 % radius 0.35 um
MACRO = CaptureUncertainty(8.6e-6, 10.8e-6, 4e-3)        # 95 % radius 26 um


def test_reached_only_when_distance_plus_uncertainty_is_within_tolerance():
    config = FeedbackConfig(tolerance_m=0.5e-6)
    close = settled_controller(config)
    # 0.2 um from the goal, but the capture is only good to 0.35 um: not proven yet.
    move = a_move(close.on_capture(Observation(0.2, 0.1 - 0.2e-6, 0.0, 0.0, 'micro', MICRO)))
    assert move.duration_s > 0
    sharper = settled_controller(config)
    end = an_end(sharper.on_capture(
        Observation(0.2, 0.1 - 0.1e-6, 0.0, 0.0, 'micro', MICRO.averaged(5))))
    assert end.outcome is Outcome.REACHED
    assert '0.10 um' in end.reason and '+-0.16 um at 95 %' in end.reason


def test_a_camera_that_cannot_resolve_the_tolerance_ends_unresolved_with_its_resolution():
    controller = settled_controller(FeedbackConfig(tolerance_m=3e-6))
    # The macro camera says 2.4 um: within tolerance by its numbers, but it sees to 26 um.
    end = an_end(controller.on_capture(Observation(0.2, 0.1 - 2.44e-6, 0.0, 0.0, 'macro',
                                                   MACRO)))
    assert end.outcome is Outcome.UNRESOLVED
    assert 'macro' in end.reason and '+-26.44 um' in end.reason and '3.00 um' in end.reason
    # Farther than the camera's uncertainty: it keeps moving toward the goal.
    far = settled_controller(FeedbackConfig(tolerance_m=3e-6))
    a_move(far.on_capture(Observation(0.2, 0.1 - 60e-6, 0.0, 0.0, 'macro', MACRO)))


def test_a_stop_averages_its_captures_and_their_spread_shrinks():
    controller = settled_controller(FeedbackConfig(captures_per_stop=4, tolerance_m=0.5e-6))
    xs = [0.1 - 0.4e-6, 0.1 + 0.1e-6, 0.1 - 0.3e-6, 0.1 + 0.2e-6]   # mean 0.1 - 0.1e-6
    decisions = [controller.on_capture(Observation(0.2 + k / 30, x, 0.0, 0.0, 'micro', MICRO))
                 for k, x in enumerate(xs)]
    assert decisions[:3] == [None, None, None]
    end = an_end(decisions[3])
    assert end.outcome is Outcome.REACHED
    seen = end.observation
    assert seen is not None and seen.count == 4 and seen.stamp_s == pytest.approx(0.3)
    assert seen.x_m == pytest.approx(0.1 - 0.1e-6, abs=1e-15)
    assert seen.radius_95_m == pytest.approx(MICRO.radius_95_m / 2)


def test_a_camera_change_within_a_stop_starts_the_average_again():
    controller = settled_controller(FeedbackConfig(captures_per_stop=2))
    assert controller.on_capture(Observation(0.2, 0.05, 0.0, 0.0, 'macro', MACRO)) is None
    assert controller.on_capture(Observation(0.23, 0.05, 0.0, 0.0, 'micro', MICRO)) is None
    move = a_move(controller.on_capture(Observation(0.26, 0.05, 0.0, 0.0, 'micro', MICRO)))
    assert move.observation.camera == 'micro' and move.observation.count == 2


@pytest.mark.parametrize('mode, expected', [('paper', 1), ('model', MODEL_CAPTURES_PER_STOP)])
def test_captures_per_stop_zero_means_the_modes_own(mode, expected):
    assert FeedbackConfig(mode=mode).captures_per_stop == expected


@pytest.mark.parametrize('changes, message', [
    ({'mode': 'magic'}, "mode must be one of ['paper', 'model', 'servo'], got 'magic'"),
    ({'captures_per_stop': -1}, 'captures_per_stop must be a whole number >= 1, got -1'),
    # Unbounded, 1e9 s ran the robot off the platform for 1,276 s before the run timed out.
    ({'open_loop_duration_s': 1e9}, 'open_loop_duration_s must be at most 60 s (at cruise '
                                    'speed 861 mm, past any platform), got 1000000000.0'),
    ({'open_loop_to_goal': 'yes'}, "open_loop_to_goal must be true or false, and false with an "
                                   "open_loop_duration_s, got 'yes'"),
    ({'open_loop_to_goal': True, 'open_loop_duration_s': 7.0},
     'open_loop_to_goal must be true or false, and false with an open_loop_duration_s, got '
     'True'),
])
def test_bad_mode_settings_are_refused_naming_the_value(changes, message):
    with pytest.raises(ControllerConfigError, match=re.escape(message)):
        FeedbackConfig(**changes)
