"""A recorder in the lockstep: the robot runs at most RECORDER_LEAD_TICKS past the ticks it has
recorded, so that no stream's writer (a status's keeps 10) drops a sample the recorder has not
had; a recorder that keeps up holds nothing (omni_micro_common.lockstep, ``recorded_ns``)."""

from __future__ import annotations

import pytest

from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import RECORDER_LEAD_TICKS, Ack, LockstepGate
from omni_micro_common.lockstep_groups import LockstepGroups

MS = 1_000_000
PERIOD = 20 * MS
LEAD = 40 * MS


def test_a_recorder_behind_holds_the_robot_within_the_writers_history():
    gate = LockstepGate(['controller_node', 'bag_recorder'], PERIOD, LEAD)
    # Before its first word it holds time at the lead, as any node does.
    gate.on_ack(Ack('controller_node', 20_000 * MS))
    assert gate.reachable_ns() == LEAD
    gate.on_ack(Ack('bag_recorder', None, recorded_ns=1_000 * MS))
    # The controller is 19 s ahead of the recorder: the recorder's bound decides.
    assert gate.reachable_ns() == 1_000 * MS + RECORDER_LEAD_TICKS * PERIOD
    assert RECORDER_LEAD_TICKS * PERIOD <= 200 * MS   # a status writer keeps 10, one a period
    # Once it has nearly caught up the controller's lead decides again.
    gate.on_ack(Ack('bag_recorder', None, recorded_ns=19_990 * MS))
    assert gate.reachable_ns() == 20_000 * MS + LEAD


def test_after_a_reset_a_recorder_counts_as_caught_up_and_still_bounds_the_robot():
    gate = LockstepGate(['controller_node', 'bag_recorder'], PERIOD, LEAD)
    gate.on_ack(Ack('bag_recorder', None, recorded_ns=100 * MS))
    gate.reset(5_000 * MS)
    gate.on_ack(Ack('controller_node', 50_000 * MS))
    assert gate.reachable_ns() == 5_000 * MS + RECORDER_LEAD_TICKS * PERIOD


def test_a_recorder_outside_every_namespace_bounds_every_robot():
    groups = LockstepGroups(['robot_0', 'robot_1'],
                            ['robot_0/controller_node', 'robot_1/controller_node',
                             'bag_recorder'], PERIOD, LEAD)
    groups.on_ack(Ack('bag_recorder', None, recorded_ns=0))
    for robot in ('robot_0', 'robot_1'):
        groups.on_ack(Ack(f'{robot}/controller_node', 60_000 * MS))
    assert groups.reachable_ns() == RECORDER_LEAD_TICKS * PERIOD


def test_a_recorders_report_round_trips_and_stands_alone():
    ack = Ack('bag_recorder', None, recorded_ns=123 * MS)
    assert Ack.from_values('bag_recorder', ack.to_values()) == ack
    with pytest.raises(LockstepError, match="recorded_ns must be a whole number"):
        Ack.from_values('bag_recorder', [('recorded_ns', 'soon')])
