"""A run's messages made into identification's chains without a bag: rclpy's own message types
(what a live subscriber holds), the moves exactly as controller_node publishes them."""

from __future__ import annotations

import math

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped

from omni_micro_common.conventions import CaptureUncertainty, split_stamp
from omni_micro_common.topic_names import CAPTURE_COVARIANCE_TOPICS
from omni_micro_control.controller_messages import move_trajectory
from omni_micro_control.errors import RecordingError
from omni_micro_control.feedback import Move
from omni_micro_control.observations import Observation
from omni_micro_control.recorded_runs import (
    WHEEL_TRAJECTORY_TOPIC,
    TooLittleRecordedError,
    read_run,
)
from omni_micro_sim.profile import move_profile

SPREAD = CaptureUncertainty(2e-6, 2e-6, 1e-3)


def capture(stamp_s: float, x_m: float, covariance: list[float] | None = None
            ) -> PoseWithCovarianceStamped:
    msg = PoseWithCovarianceStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = split_stamp(stamp_s)
    msg.header.frame_id = 'platform'
    msg.pose.pose.position.x = x_m
    msg.pose.pose.orientation.w = 1.0
    msg.pose.covariance = covariance or SPREAD.covariance()
    return msg


def move_at(start_s: float, duration_s: float):
    seen = Observation(start_s, 0.0, 0.0, 0.0, 'macro')
    return move_trajectory(Move(start_s, 0.0, duration_s, 1, 0.01, seen),
                           move_profile(duration_s), 'base_link')


def test_two_moves_between_three_seen_stops_make_one_chain():
    profile_s = move_profile(0.2).end_time_s
    messages = {
        WHEEL_TRAJECTORY_TOPIC: [move_at(1.0, 0.2), move_at(3.0, 0.2)],
        CAPTURE_COVARIANCE_TOPICS['macro']: [
            capture(0.5, 0.0), capture(0.6, 0.0),                      # before the first move
            capture(1.0 + profile_s + 0.5, 0.00029),                   # after it
            capture(3.0 + profile_s + 0.5, 0.00058)],                  # after the second
    }
    run = read_run(messages, 'live')
    assert run.moves == 2 and run.captures == 4 and len(run.chains) == 1
    chain = run.chains[0]
    assert [round(stop.x_m, 6) for stop in chain.stops] == [0.0, 0.00029, 0.00058]
    # Two captures of the first stop: their mean, with the spread of a mean of two.
    assert math.isclose(chain.stops[0].uncertainty.x_sigma_m, 2e-6 / math.sqrt(2))
    assert [move.profile.end_time_s for move in chain.moves] == [profile_s, profile_s]


def test_a_capture_with_a_broken_covariance_is_named_with_its_source():
    bad = [0.0] * 36
    bad[0] = -1.0
    messages = {WHEEL_TRAJECTORY_TOPIC: [move_at(1.0, 0.2)],
                CAPTURE_COVARIANCE_TOPICS['macro']: [capture(0.5, 0.0, bad)]}
    with pytest.raises(RecordingError, match=r"^'run 7': a macro capture at 500000000 ns: "
                                             r'the x variance'):
        read_run(messages, 'run 7')


@pytest.mark.parametrize('messages, said', [
    ({CAPTURE_COVARIANCE_TOPICS['macro']: [capture(0.5, 0.0)]}, 'has no move'),
    ({WHEEL_TRAJECTORY_TOPIC: [move_at(1.0, 0.2)]}, 'has no capture'),
])
def test_too_little_recorded_is_not_a_malformed_recording(messages, said):
    with pytest.raises(TooLittleRecordedError, match=said):
        read_run(messages, 'live')


def test_a_servo_move_corrected_while_rolling_links_no_stops_and_an_uncorrected_one_does():
    """A servo's plan made while rolling replaces the running move: the move it cut short, and
    it, are no command the slip core replays from rest, so only the uncorrected move is linked."""
    from omni_micro_control.servo import profile_to
    from omni_micro_control.servo_config import ServoCommand
    from omni_micro_sim.parameters import MotorLimits

    limits = MotorLimits()
    first = ServoCommand(1.0, 0.0, profile_to(0.0, 60.0, limits, 0.5, 0.1))
    replanned = ServoCommand(2.0, 0.0, profile_to(8.7, 40.0, limits, 0.5, 0.1), from_rest=False)
    end = replanned.start_s + replanned.profile.end_time_s
    last = ServoCommand(end + 1.0, 0.0, profile_to(0.0, 0.2, limits, 0.5, 0.1))
    messages = {
        WHEEL_TRAJECTORY_TOPIC: [move_trajectory(command, command.profile, 'base_link')
                                 for command in (first, replanned, last)],
        CAPTURE_COVARIANCE_TOPICS['macro']: [
            capture(0.5, 0.0),                                              # before the first
            capture(end + 0.5, 0.1),                                        # after the replan
            capture(last.start_s + last.profile.end_time_s + 0.5, 0.1003)],  # after the last
    }
    run = read_run(messages, 'servo')
    assert run.moves == 1 and len(run.chains) == 1
    assert run.chains[0].moves[0].profile.end_time_s == pytest.approx(last.profile.end_time_s)
    assert [stop.x_m for stop in run.chains[0].stops] == [0.1, 0.1003]
