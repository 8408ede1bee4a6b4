"""One lockstep over several robots: each robot's captures and commands held by its own nodes,
time no further than the slowest robot allows, a node outside every namespace in all."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import Ack, LockstepGate
from omni_micro_common.lockstep_groups import LockstepGroups, qualified_node_name

MS = 1_000_000
PERIOD = 20 * MS
LEAD = 40 * MS


def test_a_node_names_itself_with_its_robots_namespace():
    assert qualified_node_name('/', 'controller_node') == 'controller_node'
    assert qualified_node_name('/robot_1', 'controller_node') == 'robot_1/controller_node'
    assert qualified_node_name('robot_1/', 'vision_node') == 'robot_1/vision_node'


def test_the_slowest_robot_holds_every_robot():
    groups = LockstepGroups(['robot_0', 'robot_1'],
                            ['robot_0/controller_node', 'robot_1/controller_node'], PERIOD, LEAD)
    groups.on_ack(Ack('robot_0/controller_node', 500 * MS))
    groups.on_ack(Ack('robot_1/controller_node', 100 * MS))
    assert groups.reachable_ns() == 100 * MS + LEAD
    assert groups.waiting_for() == 'robot_1: robot_1/controller_node at 100000000 ns'
    groups.on_ack(Ack('robot_1/controller_node', 600 * MS))
    assert groups.reachable_ns() == 500 * MS + LEAD


def test_a_command_holds_time_until_its_own_robot_has_it():
    groups = LockstepGroups(['robot_0', 'robot_1'],
                            ['robot_0/controller_node', 'robot_1/controller_node'], PERIOD, LEAD)
    groups.on_ack(Ack('robot_0/controller_node', 100 * MS))
    groups.on_ack(Ack('robot_1/controller_node', 100 * MS, command_ns=120 * MS))
    assert groups.reachable_ns() == -math.inf
    groups.on_command('robot_0', 120 * MS)   # robot 0 receiving it changes nothing
    assert groups.reachable_ns() == -math.inf
    groups.on_command('robot_1', 120 * MS)
    assert groups.reachable_ns() == 100 * MS + LEAD


def test_a_capture_is_held_for_its_own_robots_controller_only():
    """Robot 0's camera reports a capture: robot 0's controller must handle it; robot 1's
    controller, which never sees it, does not hold time for it."""
    nodes = ['robot_0/vision_node', 'robot_0/controller_node', 'robot_1/vision_node',
             'robot_1/controller_node']
    groups = LockstepGroups(['robot_0', 'robot_1'], nodes, PERIOD, LEAD)
    for name in nodes:
        groups.on_ack(Ack(name, 200 * MS, capture_handled_ns=0
                          if name.endswith('controller_node') else None))
    groups.on_ack(Ack('robot_0/vision_node', 200 * MS, captures_ns=(180 * MS, 180 * MS)))
    assert groups.reachable_ns() == 180 * MS + LEAD
    groups.on_ack(Ack('robot_1/controller_node', 220 * MS, capture_handled_ns=200 * MS))
    assert groups.reachable_ns() == 180 * MS + LEAD
    groups.on_ack(Ack('robot_0/controller_node', 220 * MS, capture_handled_ns=180 * MS))
    assert groups.reachable_ns() == 200 * MS + LEAD


def test_a_node_outside_every_namespace_takes_part_for_every_robot():
    groups = LockstepGroups(['robot_0', 'robot_1'],
                            ['robot_0/controller_node', 'robot_1/controller_node', 'recorder'],
                            PERIOD, LEAD)
    for name in ('robot_0/controller_node', 'robot_1/controller_node'):
        groups.on_ack(Ack(name, 400 * MS))
    groups.on_ack(Ack('recorder', 60 * MS))
    assert groups.reachable_ns() == 60 * MS + LEAD
    assert [gate.nodes for gate in groups.gates.values()] == [
        ('robot_0/controller_node', 'recorder'), ('robot_1/controller_node', 'recorder')]


def test_one_robot_is_the_single_gate():
    """The graph of one robot: its nodes in no namespace, the one gate as before."""
    nodes = ['vision_node', 'controller_node']
    groups, gate = LockstepGroups([''], nodes, PERIOD, LEAD), LockstepGate(nodes, PERIOD, LEAD)
    for lockstep in (groups, gate):
        lockstep.on_ack(Ack('vision_node', 300 * MS, captures_ns=(260 * MS, 280 * MS)))
        lockstep.on_ack(Ack('controller_node', 280 * MS, capture_handled_ns=240 * MS,
                            command_ns=300 * MS))
    assert groups.reachable_ns() == gate.reachable_ns() == -math.inf
    groups.on_command('', 300 * MS)
    gate.on_command(300 * MS)
    assert groups.reachable_ns() == gate.reachable_ns() == 260 * MS + LEAD
    assert groups.waiting_for() == gate.waiting_for()


def test_a_node_in_no_robots_namespace_is_refused_by_name():
    with pytest.raises(LockstepError, match=r"\['robot_2/controller_node'\] are in no robot"):
        LockstepGroups(['robot_0', 'robot_1'], ['robot_2/controller_node'], PERIOD, LEAD)


def test_a_goals_end_holds_time_until_the_coordinator_has_handed_out_the_next_goals():
    """A controller reports the end of its goal; once a coordinator takes part, time stands
    still until it says it has handled that end (its next goals taken), in every robot."""
    nodes = ['robot_0/controller_node', 'robot_1/controller_node', 'fleet_coordinator']
    groups = LockstepGroups(['robot_0', 'robot_1'], nodes, PERIOD, LEAD)
    groups.on_ack(Ack('fleet_coordinator', None, outcome_handled_ns=-1))
    for name in nodes[:2]:
        groups.on_ack(Ack(name, 100 * MS))
    assert groups.reachable_ns() == 100 * MS + LEAD
    groups.on_ack(Ack('robot_0/controller_node', 120 * MS, outcome_ns=110 * MS))
    assert groups.reachable_ns() == -math.inf
    assert groups.waiting_for() == ('robot_0: fleet_coordinator to handle the end of a goal at '
                                    '110000000 ns')
    groups.on_ack(Ack('fleet_coordinator', None, outcome_handled_ns=110 * MS))
    assert groups.reachable_ns() == 100 * MS + LEAD   # robot 1's controller is the slowest
    # A resume after a pause: the controller says its last end again; it was handled.
    groups.reset(140 * MS)
    groups.on_ack(Ack('robot_0/controller_node', 140 * MS, outcome_ns=110 * MS))
    groups.on_ack(Ack('robot_1/controller_node', 140 * MS))
    assert groups.reachable_ns() == 140 * MS + LEAD


def test_without_a_coordinator_a_goals_end_holds_nothing():
    """One robot's graph: the orchestration hands out goals on its own, nothing waits."""
    gate = LockstepGate(['controller_node'], PERIOD, LEAD)
    gate.on_ack(Ack('controller_node', 100 * MS, outcome_ns=90 * MS))
    assert gate.reachable_ns() == 100 * MS + LEAD


def test_an_outcome_report_round_trips_and_a_coordinators_stands_alone():
    ack = Ack('fleet_coordinator', None, outcome_handled_ns=5)
    assert Ack.from_values('fleet_coordinator', ack.to_values()) == ack
    ack = Ack('controller_node', 7, outcome_ns=3)
    assert Ack.from_values('controller_node', ack.to_values()) == ack
    with pytest.raises(LockstepError, match='none of processed_ns'):
        Ack.from_values('controller_node', [('outcome_ns', '3')])


def test_two_robots_goals_ending_at_the_same_stamp_are_each_held_for_their_own_robot():
    """The coordinator reports for each robot in its namespace: robot 0's end handled does not
    release robot 1's end at the same stamp (it once did, with one coordinator for all)."""
    nodes = [f'robot_{k}/{node}' for k in (0, 1)
             for node in ('controller_node', 'omni_micro_orchestration')]
    groups = LockstepGroups(['robot_0', 'robot_1'], nodes, PERIOD, LEAD)
    for k in (0, 1):
        groups.on_ack(Ack(f'robot_{k}/omni_micro_orchestration', None, outcome_handled_ns=-1))
        groups.on_ack(Ack(f'robot_{k}/controller_node', 600 * MS, outcome_ns=600 * MS))
    groups.on_ack(Ack('robot_0/omni_micro_orchestration', None, outcome_handled_ns=600 * MS))
    assert groups.reachable_ns() == -math.inf
    assert groups.waiting_for() == ('robot_1: robot_1/omni_micro_orchestration to handle the '
                                    'end of a goal at 600000000 ns')
    groups.on_ack(Ack('robot_1/omni_micro_orchestration', None, outcome_handled_ns=600 * MS))
    assert groups.reachable_ns() == 600 * MS + LEAD


ROBOTS = ['robot_0', 'robot_1']
NODES = [f'{robot}/{node}' for robot in ROBOTS for node in ('vision_node', 'controller_node')]
# Few stamps, on the grid: commands awaited and received, captures handled, often coincide.
TICKS_MS = st.sampled_from([0, 20, 40])
EVENTS = st.one_of(
    st.builds(lambda node, ms: ('ack', Ack(node, ms * MS)), st.sampled_from(NODES),
              TICKS_MS),
    st.builds(lambda node, ms, first: ('ack', Ack(node, ms * MS,
                                                  captures_ns=(first * MS, first * MS))),
              st.sampled_from(NODES[0::2]), TICKS_MS, TICKS_MS),
    st.builds(lambda node, ms, handled: ('ack', Ack(node, ms * MS,
                                                    capture_handled_ns=handled * MS)),
              st.sampled_from(NODES[1::2]), TICKS_MS, TICKS_MS),
    st.builds(lambda node, ms, command: ('ack', Ack(node, ms * MS, command_ns=command * MS)),
              st.sampled_from(NODES[1::2]), TICKS_MS, TICKS_MS),
    st.builds(lambda robot, command: ('command', (robot, command * MS)),
              st.sampled_from(ROBOTS), TICKS_MS),
    st.builds(lambda ms: ('reset', ms * MS), TICKS_MS))


def replayed_least(events: list[tuple[str, Any]]) -> int | float:
    """The least of the answers of gates built afresh, one per robot, from ``events``."""
    gates = {robot: LockstepGate([node for node in NODES if node.startswith(f'{robot}/')],
                                 PERIOD, LEAD) for robot in ROBOTS}
    for kind, value in events:
        if kind == 'ack':
            gates[value.node.split('/')[0]].on_ack(value)
        elif kind == 'command':
            gates[value[0]].on_command(value[1])
        elif kind == 'reset':
            for gate in gates.values():
                gate.reset(value)
    return min(gate.reachable_ns() for gate in gates.values())


@settings(max_examples=200, deadline=None)
@given(st.lists(st.tuples(EVENTS, st.booleans()), max_size=40))
def test_the_least_of_the_gates_is_kept_right_whatever_the_reports(events_and_asks):
    """Each gate keeps its answer until its reports change, and the groups the least of them
    from the gates that changed: asked at any point of any reports, commands and resets, they
    answer as gates built afresh from the same events."""
    groups = LockstepGroups(ROBOTS, NODES, PERIOD, LEAD)
    events = [event for event, _ in events_and_asks]
    for done, ((kind, value), ask) in enumerate(events_and_asks, start=1):
        if kind == 'ack':
            groups.on_ack(value)
        elif kind == 'command':
            groups.on_command(*value)
        else:
            groups.reset(value)
        if ask:
            assert groups.reachable_ns() == replayed_least(events[:done])
    assert groups.reachable_ns() == replayed_least(events)
