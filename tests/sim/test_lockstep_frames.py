"""The lockstep gate with rendered cameras: a frame not yet tracked holds time back as a capture
not yet handled does, and a tracker (which reads no odometry) is waited for only through its
frames. Reports round-trip through their DiagnosticStatus values."""

import math

import pytest

from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import Ack, LockstepGate

MS = 1_000_000
TICK = 20 * MS
LEAD = 40 * MS


def gate() -> LockstepGate:
    return LockstepGate(['camera_node', 'tracker_node', 'controller_node'], TICK, LEAD)


def test_a_frame_not_yet_tracked_holds_time_at_its_stamp_plus_the_lead():
    lockstep = gate()
    # Before the tracker's first word it counts as caught up at 0, like any node.
    assert lockstep.reachable_ns() == LEAD
    lockstep.on_ack(Ack('controller_node', 200 * MS))
    lockstep.on_ack(Ack('tracker_node', None, frame_handled_ns=0))
    lockstep.on_ack(Ack('camera_node', 40 * MS, frames_ns=(33 * MS, 33 * MS)))
    # The camera is at 40 ms, but the frame of 33 ms is not tracked yet.
    assert lockstep.reachable_ns() == 33 * MS + LEAD
    assert 'tracker_node' in (lockstep.waiting_for() or '')
    lockstep.on_ack(Ack('tracker_node', None, frame_handled_ns=33 * MS))
    assert lockstep.reachable_ns() == 40 * MS + LEAD


def test_the_tracker_s_capture_then_waits_for_the_controller():
    lockstep = gate()
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=-1))
    lockstep.on_ack(Ack('camera_node', 80 * MS, frames_ns=(67 * MS, 67 * MS)))
    # Tracked, and it gave a capture: now the capture holds time, not the frame.
    lockstep.on_ack(Ack('tracker_node', None, captures_ns=(67 * MS, 67 * MS),
                        frame_handled_ns=67 * MS))
    assert lockstep.reachable_ns() == 67 * MS + LEAD
    # A stalled graph's log names the capture, not the slowest node's odometry.
    assert lockstep.waiting_for() == f'controller_node to handle the capture at {67 * MS} ns'
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=67 * MS))
    assert lockstep.reachable_ns() == 80 * MS + LEAD
    assert 'capture' not in (lockstep.waiting_for() or '')


def test_a_frame_is_handled_only_when_every_consumer_has_it():
    """The recorder keeping every frame takes part as a second consumer."""
    lockstep = LockstepGate(['camera_node', 'tracker_node', 'bag_recorder'], TICK, LEAD)
    lockstep.on_ack(Ack('camera_node', 140 * MS, frames_ns=(133 * MS, 133 * MS)))
    lockstep.on_ack(Ack('tracker_node', None, frame_handled_ns=133 * MS))
    lockstep.on_ack(Ack('bag_recorder', None, frame_handled_ns=100 * MS))
    assert lockstep.reachable_ns() == 133 * MS + LEAD
    lockstep.on_ack(Ack('bag_recorder', None, frame_handled_ns=133 * MS))
    assert lockstep.reachable_ns() == 140 * MS + LEAD


def test_with_only_trackers_there_is_nothing_to_go_by():
    lockstep = LockstepGate(['tracker_node'], TICK, LEAD)
    lockstep.on_ack(Ack('tracker_node', None, frame_handled_ns=0))
    assert lockstep.reachable_ns() == -math.inf


def test_frame_fields_round_trip_and_malformed_reports_are_named():
    ack = Ack('tracker_node', None, captures_ns=(1, 2), frames_ns=(3, 4), frame_handled_ns=5)
    assert Ack.from_values('tracker_node', ack.to_values()) == ack
    with pytest.raises(LockstepError, match='none of processed_ns, frame_handled_ns, '
                                            'command_handled_ns, outcome_handled_ns and '
                                            'recorded_ns'):
        Ack.from_values('x', [('capture_first_ns', '1'), ('capture_last_ns', '2')])
    with pytest.raises(LockstepError, match='frame_first_ns and frame_last_ns come together'):
        Ack.from_values('x', [('processed_ns', '1'), ('frame_first_ns', '1')])


def test_a_pending_frame_holds_the_robot_at_its_stamp_plus_the_move_lead_exactly():
    """With moves starting 50 ms after their capture, a frame at 33.3 ms lets the robot reach
    83.3 ms (the 80 ms tick: the camera can render the next frame, due at 66.7 ms, while the
    tracker reads this one), never past the start of the move it may cause."""
    lockstep = gate()
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=-1,
                        command_lead_ns=50 * MS))
    lockstep.on_ack(Ack('tracker_node', None, frame_handled_ns=0))
    frame = 33_333_333
    lockstep.on_ack(Ack('camera_node', 40 * MS, frames_ns=(frame, frame)))
    lockstep.on_ack(Ack('camera_node', 60 * MS))
    assert lockstep.reachable_ns() == frame + 50 * MS       # a whole-tick 40 ms: only 60 ms
    assert lockstep.reachable_ns() // TICK * TICK == 80 * MS
    # The processed stamps still go by whole ticks of the (capped) 40 ms lead.
    lockstep.on_ack(Ack('tracker_node', None, frame_handled_ns=frame))
    assert lockstep.reachable_ns() == 60 * MS + LEAD
