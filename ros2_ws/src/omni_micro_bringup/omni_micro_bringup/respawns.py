"""A node respawned in the middle of a run, brought back: the clock held while it comes up, its
new readers told from the dead process's, the goal its robot was driving to given again (a new
camera's, until the controller acts on it), and time started anew if it stands still (the
orchestration's part in supervision; graph.Graph respawns the process). One way for every
robot: the single robot's nodes (``vision_node``) are robot 0's in the root namespace, a fleet
robot's (``robot_1.controller_node``) are told in its namespace."""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

from omni_micro_bringup.composition import READS_FROM_ROBOT
from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.supervisor import Supervisor
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_TOPICS,
    GOAL_TOPIC,
    namespaced_topic,
    robot_index,
)
from omni_micro_control.feedback import OUTCOME_NAMES, REPLACED_REASON

# After a respawn: wall seconds with no new sample before the clock is stopped and started
# again, and how far simulated time must go (beyond the lockstep's lead) to show that the
# new process reports.
RESUME_STALL_S = 3.0
RESUMED_AFTER_S = 0.2
# How long the goal given again waits for its readers' acknowledgments. A killed process's
# reader of /goal_pose stays matched until its participant's lease runs out (Fast DDS: 20 s)
# and never acknowledges: the goal's usual wait (GOAL_READERS_MATCH_S) then ran out every time,
# 5 s of every controller respawn (measured: its first period 5.1 s after the goal). Living
# readers acknowledge within milliseconds, and the goal is sent again until the controller
# takes it.
GOAL_ACKED_WITHIN_S = 0.5


class RespawnsHost(Protocol):
    """What bringing a node back needs of the orchestration's node
    (:class:`omni_micro_bringup.orchestrator.Orchestrator` for a single robot,
    :class:`omni_micro_bringup.fleet_coordinator.FleetCoordinator` for a fleet): its ROS node, the
    clock, the robots' statuses and a way to hand a robot its goal again."""

    node: Any
    echo: Callable[[str], None] | None
    # Every robot's controller statuses, in the order read: (robot, status); the single robot
    # is robot 0.
    statuses: list[tuple[int, dict[str, str]]]

    def simulated_time_s(self) -> float | None:
        """How far the robots' time has gone, as this node has read it (None: not yet)."""
        ...

    def set_paused(self, graph: Supervisor, paused: bool) -> None: ...

    def spin_for(self, seconds: float) -> None: ...

    def let_matching_settle(self) -> None: ...

    def give_again(self, graph: Supervisor, robot: int, goal: Any) -> None:
        """Hand ``robot`` the goal it was driving to (``goal``, as the caller gave it) again,
        stamped as before, and wait until its controller has taken it."""
        ...


@dataclass(frozen=True)
class CameraWatch:
    """A robot's new camera, not acted on yet by its controller: how many statuses there were
    when its goal was last given, when, and how many times it has been given again."""

    statuses_seen: int
    asked_at: float
    tries: int


class Respawns:
    """What the orchestrator does when its supervisor says nodes were respawned."""

    def __init__(self, monitor: RespawnsHost, processes: list[str]) -> None:
        self.monitor = monitor
        self.processes = processes   # those that may be respawned (graph.Graph's, --respawn)
        self.known_endpoints: dict[str, set[bytes]] = {}
        # Robots whose new camera their controller has not acted on yet.
        self.watched: dict[int, CameraWatch] = {}
        self.namespaces: dict[int, str] = {}   # each robot's, as its respawned nodes named it

    # What each respawnable node reads; of alternatives, whichever it subscribes (the
    # controller reads captures with their covariance, or bare ones).
    # What they read from the robot is the composition's (READS_FROM_ROBOT).
    INPUTS: ClassVar[dict[str, tuple[tuple[str, ...], ...]]] = {
        'vision_node': tuple((topic,) for topic in READS_FROM_ROBOT['vision_node']),
        'controller_node': (*((topic,) for topic in READS_FROM_ROBOT['controller_node']),
                            (GOAL_TOPIC,),
                            (CAPTURE_COVARIANCE_TOPICS['macro'], CAPTURE_TOPICS['macro']))}

    def _readers(self, process: str, topics: tuple[str, ...]) -> list[Any]:
        """The readers of ``topics`` (a robot's own in its namespace) that the node of
        ``process`` (``vision_node``, ``robot_1.vision_node``) holds."""
        namespace, _, name = process.rpartition('.')
        return [info for topic in topics
                for info in self.monitor.node.get_subscriptions_info_by_topic(
                    namespaced_topic(namespace, topic))
                if info.node_name == name and info.node_namespace == f'/{namespace}']

    def _endpoints(self, process: str) -> set[bytes]:
        return {bytes(info.endpoint_gid) for topics in self._inputs(process)
                for info in self._readers(process, topics)}

    def _inputs(self, process: str) -> tuple[tuple[str, ...], ...]:
        return self.INPUTS.get(process.rpartition('.')[2], ())

    def _has_new_endpoints(self, process: str) -> bool:
        known = self.known_endpoints.get(process, set())
        return all(any(bytes(info.endpoint_gid) not in known
                       for info in self._readers(process, topics))
                   for topics in self._inputs(process))

    def remember_endpoints(self) -> None:
        """Note the readers of every respawnable node, to tell a new process's from a ghost's."""
        self.known_endpoints = {process: self._endpoints(process) for process in self.processes}

    def note_endpoints_at_start(self) -> None:
        """Once the graph is up: the respawnable nodes' readers, noted. A respawned node is
        told from its ghost by readers that were not there at the start, so every one of those
        must be seen first: discovery shows an endpoint a little before every peer has it."""
        if self.processes:
            self.monitor.let_matching_settle()
        self.remember_endpoints()

    def wait_for_new_processes(self, graph: Supervisor, restarted: list[str]) -> None:
        """With the clock held: until each respawned node is up and in the ROS graph.

        The dead node's endpoints stay in the ROS graph until their lease runs out, so a count
        of subscribers cannot tell: wait for the new process to say it is ready and for
        endpoints of it that were not there before to appear on the topics it reads."""
        for name in restarted:
            if not graph.wait_ready(name, 60.0):
                raise RunFailed(f'respawned {name} did not come up within 60 s')
            deadline = time.monotonic() + 60.0
            while not self._has_new_endpoints(name):
                graph.check_alive()
                if time.monotonic() > deadline:
                    raise RunFailed(f'respawned {name} was not discovered within 60 s')
                self.monitor.spin_for(0.05)
        self.monitor.let_matching_settle()
        graph.check_alive()

    def bring_back(self, graph: Supervisor, restarted: list[str], driving: Mapping[int, Any],
                   handled_up_to: int) -> None:
        """Nodes were respawned: hold the clock while they come back, hand each of their robots
        the goal it was driving to again, and go on from there.

        ``driving``: each robot's goal under way, as :meth:`RespawnsHost.give_again` takes it;
        ``handled_up_to``: how many of the robots' statuses the orchestration has handled. A
        robot whose goal ended in a status not handled yet is not given it again (it would end
        twice). A robot with a new camera is watched until its controller acts on a capture
        (:meth:`watch_new_cameras`)."""
        self.monitor.set_paused(graph, True)
        self.wait_for_new_processes(graph, restarted)
        nodes: dict[int, set[str]] = {}
        for name in restarted:
            namespace, _, node = name.rpartition('.')
            # The single robot's nodes are in the root namespace: robot 0 of a fleet of one.
            index = robot_index(namespace) if namespace else 0
            if index is not None:
                nodes.setdefault(index, set()).add(node)
                self.namespaces[index] = namespace
        ended = {robot for robot, status in self.monitor.statuses[handled_up_to:]
                 if ends_a_goal(status)}
        for robot in sorted(robot for robot in nodes if robot in driving and robot not in ended):
            # A new controller knows nothing; an old one, its camera gone a while, ends the goal
            # as replaced and takes it again.
            since = len(self.monitor.statuses)
            self.monitor.give_again(graph, robot, driving[robot])
            if 'vision_node' in nodes[robot]:
                self.watched[robot] = CameraWatch(since, time.monotonic(), 0)
        self.remember_endpoints()
        if ended:
            # A fleet's time stands at those ends until the coordinator has handled them: it
            # goes on once it has, and cannot be seen to move before.
            self.monitor.set_paused(graph, False)
        else:
            self.resume(graph, restarted)

    def watch_new_cameras(self, graph: Supervisor, driving: Mapping[int, Any]) -> None:
        """Between the orchestration's looks at the statuses: each robot with a new camera
        watched until its controller acts on a capture of it (its reader may match the new
        writer later than the ROS graph shows), the goal given again every 3 s meanwhile. Not
        waited for in a loop of its own: a fleet's time stands at any other robot's end until the
        coordinator handles it."""
        for robot, watch in list(self.watched.items()):
            statuses = self.monitor.statuses
            if robot not in driving or any(
                    k == robot and (status['message'] == 'moving' or ends_a_goal(status))
                    for k, status in statuses[watch.statuses_seen:]):
                del self.watched[robot]
            elif time.monotonic() - watch.asked_at >= 3.0:
                if watch.tries >= 20:
                    namespace = self.namespaces.get(robot, '')
                    whose = f"{namespace}'s " if namespace else ''
                    raise RunFailed(f'{whose}controller_node receives no capture from its '
                                    'respawned vision_node')
                self.watched[robot] = CameraWatch(len(statuses), time.monotonic(), watch.tries + 1)
                self.monitor.give_again(graph, robot, driving[robot])

    def resume(self, graph: Supervisor, restarted: list[str],
               stall_s: float = RESUME_STALL_S) -> None:
        """Start the clock held for the respawn of ``restarted`` and wait until simulated time
        has gone well past where it stood; if it stands still instead, stop it and start it
        again.

        The robot starts time once its publishers have matched the readers it sees of the
        respawned node. A dead process's reader stays in the ROS graph for a while and, in the
        robot's view, can stand in for the new one not yet discovered there: the new process
        then loses the first samples, never reports them, and the lockstep would wait for ever
        (a slow CI run: "respawned vision_node published no capture within 60 s"). Starting the
        clock again levels every node at the time it stands at and looks at the readers anew.
        """
        self.monitor.set_paused(graph, False)
        self._wait_for_time_to_move(graph, restarted, stall_s)

    def _wait_for_time_to_move(self, graph: Supervisor, restarted: list[str],
                               stall_s: float) -> None:
        deadline = time.monotonic() + 60.0
        first: float | None = None
        latest = self.monitor.simulated_time_s()
        moved_at = time.monotonic()
        while True:
            graph.check_alive()
            self.monitor.spin_for(0.05)
            stamp = self.monitor.simulated_time_s()
            if stamp != latest:
                latest, moved_at = stamp, time.monotonic()
                first = stamp if first is None else first
            if latest is not None and first is not None and latest - first >= RESUMED_AFTER_S:
                return
            if time.monotonic() > deadline:
                raise RunFailed(f'simulated time stands still after respawning '
                                f'{", ".join(restarted)}')
            if time.monotonic() - moved_at >= stall_s:
                if self.monitor.echo:
                    self.monitor.echo(f'[orchestration] simulated time stands still at '
                              f'{latest or 0.0:.2f} s after respawning {", ".join(restarted)}: '
                              'stopping and starting the clock again')
                self.monitor.set_paused(graph, True)
                self.monitor.let_matching_settle()
                first, moved_at = None, time.monotonic()
                self.monitor.set_paused(graph, False)


def ends_a_goal(status: dict[str, str]) -> bool:
    """A controller's outcome, but not the end of a goal replaced by the same one given again."""
    return status['message'] in OUTCOME_NAMES and status.get('reason') != REPLACED_REASON
