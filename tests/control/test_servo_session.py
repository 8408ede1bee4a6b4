"""The servo as the controller node and the twin drive it (omni_micro_control.servo_session):
when a command made while rolling starts, when the wheels' stop counts, and how a goal ends."""

import math

import pytest

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_control.feedback import REPLACED_REASON, Finished, Outcome, Phase
from omni_micro_control.observations import CapturesBeforeTheGoal, Observation
from omni_micro_control.servo import ServoController
from omni_micro_control.servo_config import ServoCommand, ServoConfig
from omni_micro_control.servo_session import OUT_OF_FIELD_REASON, ServoSession
from omni_micro_sim.parameters import MotorLimits, RobotParameters
from omni_micro_studies.twin import run_servo

MICRO = CaptureUncertainty(0.07e-6, 0.07e-6, 1e-4)


def test_a_plan_made_while_rolling_starts_on_the_grid_after_the_capture_s_age_and_lead(
        monkeypatch):
    """Its start is a function of the capture's stamp alone, never of when it was handled."""
    made = []
    original = ServoController.on_capture_in_motion

    def watched(self, seen):
        command = original(self, seen)
        if command is not None:
            made.append((seen.stamp_s, command.start_s, self.config))
        return command

    monkeypatch.setattr(ServoController, 'on_capture_in_motion', watched)
    run_servo((0.01, 0.0), robot=RobotParameters(), seed=1)
    assert len(made) > 5
    for stamp, start, config in made:
        earliest = stamp + config.capture_age_s + config.command_lead_s
        ticks = start / config.command_period_s
        assert earliest - 1e-9 <= start < earliest + config.command_period_s
        assert abs(ticks - round(ticks)) < 1e-9
    # The twin took the age from its cameras: half the 4 ms exposure and one 20 ms tick.
    assert made[0][2].capture_age_s == 0.002 + 0.02


def session_at_rest(goal_m=(0.001, 0.0)) -> ServoSession:
    session = ServoSession(ServoConfig(captures_per_stop=1), MotorLimits(), RobotParameters())
    session.set_goal(goal_m, 0.0)
    return session


def test_a_goal_rolls_from_its_first_capture_and_its_wheels_stop_only_after_the_command():
    session = session_at_rest()
    assert session.phase is Phase.SETTLING
    command = session.on_capture(Observation(0.2, 0.0, 0.0, 0.0, 'micro', MICRO))
    assert isinstance(command, ServoCommand)
    assert command.from_rest and session.phase is Phase.MOVING
    end = command.start_s + command.profile.end_time_s
    session.on_wheel_state(end - 0.02, (0.0, 0.0, 0.0))   # steering stops them: no end
    session.on_wheel_state(end, (0.0, 0.1, 0.0))           # still turning: no end
    assert session.phase is Phase.MOVING
    session.on_wheel_state(end, (0.0, 0.0, 0.0))
    assert session.phase is Phase.SETTLING and session.servo.stops == 1


def test_a_goal_ends_once_lost_replaced_or_cancelled_and_says_so():
    session = session_at_rest()
    session.on_capture(Observation(0.2, 0.0, 0.0, 0.0, 'micro', MICRO))
    replaced = session.set_goal((0.002, 0.0), 0.5)
    assert replaced is not None and replaced.outcome is Outcome.CANCELLED
    assert replaced.reason == REPLACED_REASON and replaced.periods == 1
    lost = session.on_out_of_field(0.6)
    assert lost is not None and lost.outcome is Outcome.LOST and lost.reason == OUT_OF_FIELD_REASON
    assert session.phase is Phase.DONE
    assert session.on_out_of_field(0.7) is None and session.cancel('shutdown') is None


def test_the_goal_reached_is_the_sharpest_camera_s_mean_within_the_tolerance():
    session = session_at_rest(goal_m=(0.0, 0.0))
    finished = session.on_capture(Observation(0.2, 0.1e-6, 0.0, 0.0, 'micro', MICRO))
    assert isinstance(finished, Finished) and finished.outcome is Outcome.REACHED
    assert finished.observation is not None and finished.periods == 0
    assert math.isclose(finished.observation.x_m, 0.1e-6)


def test_a_stop_and_go_loop_asked_for_the_servo_refuses_rather_than_run_the_paper_s_rule():
    from omni_micro_control.errors import ControllerConfigError
    from omni_micro_control.feedback_config import FeedbackConfig
    from omni_micro_control.model_based import planner_for

    with pytest.raises(ControllerConfigError, match='servo mode plans no stop-and-go moves'):
        planner_for(FeedbackConfig(mode='servo'))


def test_a_capture_in_motion_counts_by_its_stamp_whether_the_stop_came_first_or_not():
    """A node receives the wheels' stop and a late capture in either order: the same state."""
    states = []
    for stop_first in (True, False):
        session = session_at_rest()
        command = session.on_capture(Observation(0.2, 0.0, 0.0, 0.0, 'micro', MICRO))
        assert isinstance(command, ServoCommand)
        end = command.start_s + command.profile.end_time_s
        late = Observation(end - 0.01, 0.9e-3, 0.0, 0.0, 'micro', MICRO)
        after = Observation(end + 0.03, 1.0e-3, 0.0, 0.0, 'micro', MICRO)
        if stop_first:
            session.on_wheel_state(end, (0.0, 0.0, 0.0))
        assert session.on_capture_in_motion(late) is None    # no wheel speed left to replan
        assert session.on_capture_in_motion(after) is None
        if not stop_first:
            session.on_wheel_state(end, (0.0, 0.0, 0.0))
        assert session.servo.filter is not None
        states.append((session.phase, session.servo.filter.updates,
                       tuple(session.servo.filter.mean)))
    assert states[0] == states[1] and states[0][1] == 1


def test_a_capture_that_is_not_finite_is_as_good_as_none():
    session = session_at_rest()
    broken = Observation(0.2, math.nan, 0.0, 0.0, 'micro', MICRO)
    assert session.on_capture(broken) is None and session.phase is Phase.SETTLING
    assert session.on_capture_in_motion(broken) is None and session.captures_in_motion == 0


@pytest.mark.parametrize(('said', 'bound'), [(None, None), ('soon', None), ('nan', None),
                                             ('-0.01', None), ('0.03', None), ('0.07', 0.07)])
def test_a_trackers_measured_age_is_the_servos_bound_only_where_it_is_later(said, bound):
    """A driver's captures in motion come as old as its tracker measures them: the servo starts
    its corrections no sooner after a capture than that, nor than its own setting."""
    session = ServoSession(ServoConfig(capture_age_s=0.05), MotorLimits(), RobotParameters())
    assert session.take_capture_age('micro', said) == bound
    assert session.config.capture_age_s == (bound or 0.05)
    # The oldest stated counts, of any camera: a later, younger statement lowers nothing.
    session.take_capture_age('macro', '0.06')
    assert session.take_capture_age('micro', '0.055') is None
    assert session.config.capture_age_s == max(bound or 0.0, 0.06)


def test_each_goal_counts_its_own_moves_and_the_filter_keeps_what_it_learnt():
    """A robot given goal after goal (a fleet's legs): the tenth goal may take its moves as the
    first did (max_moves is per goal), and the offsets learnt on one goal serve the next."""
    session = ServoSession(ServoConfig(captures_per_stop=1, max_moves=2), MotorLimits(),
                           RobotParameters())
    now = 0.0
    learnt = None
    for goal in range(4):
        session.set_goal((0.001 * (goal + 1), 0.0), now)
        at = 0.001 * goal
        command = session.on_capture(Observation(now + 0.2, at, 0.0, 0.0, 'micro', MICRO))
        assert isinstance(command, ServoCommand) and session.servo.moves == 1
        if learnt is not None:
            assert session.servo.filter is learnt   # the same estimate, restarted from here
        learnt = session.servo.filter
        end = command.start_s + command.profile.end_time_s
        session.on_wheel_state(end, (0.0, 0.0, 0.0))
        now = end + session.config.settle_wait_s
        finished = session.on_capture(Observation(now, 0.001 * (goal + 1), 0.0, 0.0, 'micro',
                                                  MICRO))
        assert isinstance(finished, Finished) and finished.outcome is Outcome.REACHED
        assert finished.periods == 1 and session.servo.stops == 1


def test_captures_kept_before_a_goal_are_those_of_its_stamp_on_and_are_taken_once():
    held = CapturesBeforeTheGoal(kept=3)
    for stamp_s in (4.9, 5.0, 5.02, 5.04):   # the first falls out: three kept
        held.keep(Observation(stamp_s, 0.0, 0.0, 0.0))
    assert [seen.stamp_s for seen in held.since(5.01)] == [5.02, 5.04]
    assert held.since(0.0) == []
