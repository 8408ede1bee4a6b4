"""One lockstep over several robots on one clock: a gate per robot
(:class:`~omni_micro_common.lockstep.LockstepGate`), and time no further than the slowest
robot's gate allows.

A gate pairs a camera's captures with the controller that handles them and a controller's
commands with the robot that receives them; with several robots those pairs are per robot (robot
1's controller never handles robot 0's captures), so each robot's nodes report to a gate of their
own. A node is robot k's when its qualified name (:func:`qualified_node_name`) is in robot k's
namespace, ``robot_k/controller_node``; a node outside every robot's namespace (a recorder, a
watcher of all robots) takes part in every gate.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import Ack, LockstepGate


def qualified_node_name(namespace: str, name: str) -> str:
    """How a node names itself in lockstep reports and lists: ``name`` in the root namespace
    (a single robot's graph), ``robot_1/name`` in ``/robot_1``."""
    namespace = namespace.strip('/')
    return f'{namespace}/{name}' if namespace else name


def nodes_of_robot(robot: str, names: Sequence[str]) -> list[str]:
    """Which of ``names`` (each as :func:`qualified_node_name` gives it) are robot ``robot``'s:
    those in its namespace, then those outside every robot's namespace (a recorder, a watcher
    of all robots), which are every robot's."""
    return ([name for name in names if name.startswith(f'{robot}/')]
            + [name for name in names if '/' not in name])


class LockstepGroups:
    """The lockstep of ``robots`` (namespaces, e.g. ``['robot_0', 'robot_1']``) over ``nodes``.

    Raises
    ------
    LockstepError
        A node in a namespace that is no robot's (a typo would leave its robot's gate without
        it), or what :class:`LockstepGate` refuses.
    """

    def __init__(self, robots: Sequence[str], nodes: Sequence[str], period_ns: int,
                 max_lead_ns: int) -> None:
        self.robots = tuple(robots)
        self.nodes = tuple(dict.fromkeys(name for name in nodes if name))
        strangers = [name for name in self.nodes
                     if '/' in name and name.split('/', 1)[0] not in self.robots]
        if strangers:
            raise LockstepError(f'lockstep nodes {strangers} are in no robot\'s namespace '
                                f'({list(self.robots)})')
        self.gates = {robot: LockstepGate(nodes_of_robot(robot, self.nodes), period_ns,
                                          max_lead_ns) for robot in self.robots}
        self.period_ns = period_ns
        # Each node's reports go to the gates it takes part in only (a shared node's to all).
        self._gates_of = {node: [gate for gate in self.gates.values() if node in gate.nodes]
                          for node in self.nodes}
        self._enabled_gates = [gate for gate in self.gates.values() if gate.enabled]
        # The least of the gates' reachable_ns, kept up to date from the gates that changed:
        # asked after every report, it would otherwise cost each report all N gates.
        self._allowed: dict[LockstepGate, int | float] = {}
        self._changed: set[LockstepGate] = set(self._enabled_gates)
        self._least: int | float = math.inf

    @property
    def enabled(self) -> bool:
        return bool(self.nodes)

    def reset(self, now_ns: int) -> None:
        for gate in self.gates.values():
            gate.reset(now_ns)
        self._changed.update(self._enabled_gates)

    def on_ack(self, ack: Ack) -> None:
        gates = self._gates_of.get(ack.node, ())
        for gate in gates:
            gate.on_ack(ack)
        self._changed.update(gates)

    def on_command(self, robot: str, stamp_ns: int) -> None:
        """A command stamped ``stamp_ns`` reached ``robot``."""
        gate = self.gates[robot]
        gate.on_command(stamp_ns)
        if gate.enabled:
            self._changed.add(gate)

    def reachable_ns(self) -> int | float:
        """The latest grid time every robot may reach now: the least of the gates'."""
        if not self._changed:
            return self._least
        least, work_out_all = self._least, not self._allowed
        for gate in self._changed:
            before, now = self._allowed.get(gate), gate.reachable_ns()
            self._allowed[gate] = now
            work_out_all = work_out_all or (before == self._least and now > before)
            least = min(least, now)
        self._changed.clear()
        self._least = min(self._allowed.values(), default=math.inf) if work_out_all else least
        return self._least

    def waiting_for(self) -> str | None:
        """What holds time back: the gate that allows least, and what it waits for."""
        gates = [(robot, gate) for robot, gate in self.gates.items() if gate.enabled]
        if not gates:
            return None
        robot, gate = min(gates, key=lambda entry: entry[1].reachable_ns())
        waiting = gate.waiting_for()
        return f'{robot}: {waiting}' if robot and waiting else waiting
