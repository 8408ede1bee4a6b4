"""The lockstep gate with a watcher (markers_node): a node that reads no odometry but must have
every capture and command before a later sample can reach it, so that what it draws for a tick
never depends on which message reached it first."""

import pytest

from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import NOTHING_HANDLED_NS, Ack, LockstepGate

MS = 1_000_000
TICK = 20 * MS
LEAD = 40 * MS


def gate() -> LockstepGate:
    lockstep = LockstepGate(['vision_node', 'controller_node', 'markers_node'], TICK, LEAD)
    lockstep.on_ack(Ack('markers_node', None, capture_handled_ns=NOTHING_HANDLED_NS,
                        command_handled_ns=NOTHING_HANDLED_NS))
    return lockstep


def test_before_its_first_word_a_watcher_holds_time_at_the_lead_like_any_node():
    lockstep = LockstepGate(['vision_node', 'markers_node'], TICK, LEAD)
    lockstep.on_ack(Ack('vision_node', 200 * MS))
    assert lockstep.reachable_ns() == LEAD
    lockstep.on_ack(Ack('markers_node', None, capture_handled_ns=NOTHING_HANDLED_NS,
                        command_handled_ns=NOTHING_HANDLED_NS))
    assert lockstep.reachable_ns() == 200 * MS + LEAD


def test_a_capture_the_watcher_has_not_handled_holds_time_one_period_past_it():
    lockstep = gate()
    lockstep.on_ack(Ack('controller_node', 300 * MS, capture_handled_ns=100 * MS))
    lockstep.on_ack(Ack('vision_node', 300 * MS, captures_ns=(100 * MS, 100 * MS)))
    # The controller has it; the watcher not yet.
    assert lockstep.reachable_ns() == 100 * MS + TICK
    assert lockstep.waiting_for() == f'markers_node to handle the capture at {100 * MS} ns'
    lockstep.on_ack(Ack('markers_node', None, capture_handled_ns=100 * MS,
                        command_handled_ns=NOTHING_HANDLED_NS))
    assert lockstep.reachable_ns() == 300 * MS + LEAD


def test_a_command_the_watcher_has_not_handled_holds_time_still():
    lockstep = gate()
    lockstep.on_ack(Ack('vision_node', 200 * MS))
    lockstep.on_ack(Ack('controller_node', 200 * MS, command_ns=250 * MS))
    lockstep.on_command(250 * MS)   # the robot has it
    assert lockstep.reachable_ns() == -float('inf')
    assert lockstep.waiting_for() == f'markers_node to handle the command at {250 * MS} ns'
    # A heartbeat that still names an older command changes nothing.
    lockstep.on_ack(Ack('markers_node', None, capture_handled_ns=NOTHING_HANDLED_NS,
                        command_handled_ns=NOTHING_HANDLED_NS))
    assert lockstep.reachable_ns() == -float('inf')
    lockstep.on_ack(Ack('markers_node', None, capture_handled_ns=NOTHING_HANDLED_NS,
                        command_handled_ns=250 * MS))
    assert lockstep.reachable_ns() == 200 * MS + LEAD


def test_after_a_reset_a_watcher_known_to_read_no_odometry_does_not_hold_time_at_the_lead():
    """Resuming at a tick that is no throttled sample's: waiting for the watcher's stamp there
    would wait for ever (it reports when the next throttled sample comes, beyond the lead)."""
    lockstep = gate()
    lockstep.reset(1_020 * MS)
    lockstep.on_ack(Ack('vision_node', 1_020 * MS))
    lockstep.on_ack(Ack('controller_node', 1_020 * MS))
    assert lockstep.reachable_ns() == 1_020 * MS + LEAD


@pytest.mark.parametrize('values, problem', [
    ([('command_handled_ns', '5')], 'together'),
    ([('capture_handled_ns', '5')], 'none of'),
    ([('command_handled_ns', 'soon'), ('capture_handled_ns', '5')], 'whole number'),
])
def test_a_malformed_watcher_report_is_refused_and_named(values, problem):
    with pytest.raises(LockstepError, match=problem) as raised:
        Ack.from_values('markers_node', values)
    assert 'markers_node' in str(raised.value)


def test_a_watcher_report_round_trips_through_its_values():
    ack = Ack('markers_node', None, capture_handled_ns=7, command_handled_ns=9)
    assert Ack.from_values('markers_node', ack.to_values()) == ack
