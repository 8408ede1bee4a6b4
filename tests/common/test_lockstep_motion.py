"""The lockstep gate with captures in motion: a controller that acts on them (the servo) holds
the robot at a capture's stamp plus its move's lead until it has handled it, apart from the
stationary captures (the two kinds come out of stamp order); with no such controller they hold
nothing, and watchers never wait for them."""

import pytest

from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import Ack, LockstepGate

MS = 1_000_000
TICK = 20 * MS
LEAD = 40 * MS


def gate(*extra: str) -> LockstepGate:
    return LockstepGate(['vision_node', 'controller_node', *extra], TICK, LEAD)


def test_a_capture_in_motion_holds_time_until_the_servo_has_handled_it():
    lockstep = gate()
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=-1,
                        motion_handled_ns=-1))
    # Released at 120 ms, stamped at 70 ms: time is held where it is until it is handled.
    lockstep.on_ack(Ack('vision_node', 120 * MS, motion_ns=(70 * MS, 70 * MS)))
    assert lockstep.reachable_ns() == 70 * MS + LEAD
    assert lockstep.waiting_for() == (f'controller_node to handle the capture in motion at '
                                      f'{70 * MS} ns')
    # A stationary capture handled later in stamp does not stand for it.
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=100 * MS,
                        motion_handled_ns=-1))
    assert lockstep.reachable_ns() == 70 * MS + LEAD
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=100 * MS,
                        motion_handled_ns=70 * MS))
    assert lockstep.reachable_ns() == 120 * MS + LEAD


def test_without_a_controller_that_acts_on_them_captures_in_motion_hold_nothing():
    lockstep = gate('markers_node')
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=-1))
    lockstep.on_ack(Ack('markers_node', None, capture_handled_ns=-1, command_handled_ns=-1))
    lockstep.on_ack(Ack('vision_node', 120 * MS, motion_ns=(70 * MS, 70 * MS)))
    assert lockstep.reachable_ns() == 120 * MS + LEAD
    assert lockstep.waiting_for() == f'vision_node at {120 * MS} ns'


def test_motion_fields_round_trip_and_a_half_span_is_named():
    ack = Ack('vision_node', 5, motion_ns=(1, 2), motion_handled_ns=3)
    assert Ack.from_values('vision_node', ack.to_values()) == ack
    with pytest.raises(LockstepError, match=r'^lockstep report of .vision_node.: '
                       r'motion_first_ns and motion_last_ns come together$'):
        Ack.from_values('vision_node', [('processed_ns', '5'), ('motion_first_ns', '1')])


def test_a_reset_forgets_the_captures_in_motion_of_a_replaced_controller():
    lockstep = gate()
    lockstep.on_ack(Ack('controller_node', 200 * MS, capture_handled_ns=-1,
                        motion_handled_ns=-1))
    lockstep.on_ack(Ack('vision_node', 120 * MS, motion_ns=(70 * MS, 70 * MS)))
    lockstep.reset(300 * MS)
    assert lockstep.reachable_ns() == 300 * MS + LEAD
