"""The orchestration's own node: sees the graph come up, hands the controller its goal, runs and
holds the clock (dynamics_node's `paused`), brings respawned nodes back, waits for the outcome
and reads the true final pose from /odom. It commands nothing that moves the robot.

The final pose is the first odometry sample at or after the outcome's capture, not the one this
process happens to read first: a robot at rest still creeps (1e-14 m a tick), so which sample
that was would show in the last digits and depend on the machine's load. The orchestrator's reader
is one of dynamics_node's awaited readers (the composition says so): matched before time
starts, it has every sample, and keeps the last ODOMETRY_KEPT. It reads /odom_throttle (one
tick in five), or /odom when it follows the route: a reader at the full rate slows a graph at
its fastest pace, and gives a killed orchestrator's shared-memory port more traffic to be
caught holding (docs/reliability.md, "Processes")."""

from __future__ import annotations

import functools
import time
from collections import deque
from collections.abc import Callable
from typing import Any

import rclpy
from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.client import Client
from rclpy.context import Context
from rclpy.duration import Duration
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.publisher import Publisher

from omni_micro_bringup.composition import ORCHESTRATOR_NODE, orchestration_odometry_topic
from omni_micro_bringup.errors import RunFailed, UsageError
from omni_micro_bringup.readiness import Readiness
from omni_micro_bringup.recorder_watch import RecorderWatch
from omni_micro_bringup.respawns import GOAL_ACKED_WITHIN_S, Respawns, ends_a_goal
from omni_micro_bringup.supervisor import Supervisor
from omni_micro_common.conventions import (
    join_stamp,
    quaternion_to_yaw,
)
from omni_micro_common.goal_message import goal_pose
from omni_micro_common.installed import use_dds_profile
from omni_micro_common.publication_counts import PublicationCounter
from omni_micro_common.qos import CAPTURE_QOS, DATA_QOS, STATUS_QOS
from omni_micro_common.topic_names import (
    CAPTURE_TOPICS,
    CONTROLLER_STATUS_TOPIC,
    GOAL_TOPIC,
    namespaced_topic,
)

# How many of the latest odometry samples the orchestrator keeps (80 s of simulated time at 50 Hz):
# the status naming the outcome's capture reaches this process after its sample, by far less.
ODOMETRY_KEPT = 4000

# How long a graph may take to come up: its nodes to listen, the bench's drivers to publish.
READY_WITHIN_S = 60.0
# Discovery shows an endpoint a little before every peer has matched it.
MATCH_GRACE_S = 0.5
# How long a goal waits for its readers to match it and then to acknowledge it (a dead
# process's reader, still in the ROS graph, never does: the goal goes on without it).
GOAL_READERS_MATCH_S = 5.0
# How long an unanswered request to a node's parameter service (dynamics_node's clock, a fleet
# robot's tolerance) waits before it goes again: a server may answer before its response writer
# has matched this client, and the answer is lost.
SERVICE_RESEND_S = 2.0
# A recorded run goes on this far (simulated time) past the bag's end before it is stopped:
# markers_node draws an array once the odometry is two arrays (0.2 s) past it.
RUN_ON_PAST_BAG_END_S = 0.4


class Orchestrator:
    """The orchestration's node in ``domain_id``, for the robots in ``namespaces``: each one's
    goal publisher and controller's statuses, and each one's odometry as
    :meth:`_follow_odometry` keeps it. The single robot is the fleet of one in the root
    namespace, its goals handed one by one (:meth:`send_goal`); a fleet's coordinator is
    :class:`~omni_micro_bringup.fleet_coordinator.FleetCoordinator`. With ``follow_route`` it
    keeps the single robot's whole route and every capture (for figures)."""

    def __init__(self, domain_id: int, follow_route: bool = False,
                 echo: Callable[[str], None] | None = None, markers: bool = False,
                 namespaces: tuple[str, ...] = ('',), recording: bool = False,
                 respawnable: list[str] | None = None) -> None:
        self.echo = echo
        self.domain_id = domain_id
        self.recording = recording   # the recorder must have every goal, as the controller
        self.markers = markers   # markers_node is in the graph: it must have every goal
        # The graph's Fast DDS profile here too (its announcements are what makes discovery
        # quick), read when this process makes its first participant.
        use_dds_profile()
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node(ORCHESTRATOR_NODE, context=self.context)
        # The events executor: rclpy's SingleThreadedExecutor rebuilds its wait set in Python
        # on every wake-up, each subscription's event handlers too (about 60 of them for 8
        # robots), which cost this process more than the dynamics' own work.
        self.executor = EventsExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.latest_odometry: tuple[float, float, float, float] | None = None
        self.odometry: deque[tuple[float, float, float, float]] = deque(maxlen=ODOMETRY_KEPT)
        # Every robot's controller statuses, in the order read: (robot, status).
        self.statuses: list[tuple[int, dict[str, str]]] = []
        self.parameters = self.node.create_client(SetParameters, '/dynamics_node/set_parameters')
        # The goals published, per topic (each robot's writer counts what it sends).
        self.goals_published = PublicationCounter()
        self.goal_sent_at = 0
        self.goal_stamp_s = 0.0
        self.recorder = RecorderWatch(self.node, self.spin_for)
        self.route: list[tuple[float, float, float]] = []
        self.respawns = Respawns(self, respawnable or [])
        self.captures: list[tuple[float, float, float, str]] = []
        self._following = follow_route
        self.goal_publishers: list[Publisher] = []
        for robot, namespace in enumerate(namespaces):
            self.node.create_subscription(
                DiagnosticStatus, namespaced_topic(namespace, CONTROLLER_STATUS_TOPIC),
                functools.partial(self._on_status, robot), STATUS_QOS)
            self.goal_publishers.append(self.goals_published.wrap(self.node.create_publisher(
                PoseStamped, namespaced_topic(namespace, GOAL_TOPIC), 10)))
            self._follow_odometry(robot, namespace)

    def _follow_odometry(self, robot: int, namespace: str) -> None:
        """The single robot's odometry (and, ``follow_route``, its captures)."""
        self.node.create_subscription(
            Odometry, namespaced_topic(namespace, orchestration_odometry_topic(self._following)),
            self._on_odometry, DATA_QOS)
        if self._following:
            for camera, topic in CAPTURE_TOPICS.items():
                self.node.create_subscription(
                    PoseStamped, namespaced_topic(namespace, topic),
                    functools.partial(self._on_capture, camera=camera), CAPTURE_QOS)

    def _on_capture(self, msg: PoseStamped, camera: str) -> None:
        self.captures.append((join_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec),
                              msg.pose.position.x, msg.pose.position.y, camera))

    def _on_odometry(self, msg: Odometry) -> None:
        pose = msg.pose.pose
        self.latest_odometry = (join_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec),
                                pose.position.x, pose.position.y,
                                quaternion_to_yaw(pose.orientation.z, pose.orientation.w))
        self.odometry.append(self.latest_odometry)
        if self._following:
            self.route.append(self.latest_odometry[:3])

    def _on_status(self, robot: int, msg: DiagnosticStatus) -> None:
        values = {item.key: item.value for item in msg.values}
        values['message'] = msg.message
        self.statuses.append((robot, values))

    def let_matching_settle(self) -> None:
        """Discovery shows an endpoint a little before every peer has matched it."""
        self.spin_for(MATCH_GRACE_S)

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=min(0.05, max(0.0, deadline - time.monotonic())))

    def wait_until_ready(self, graph: Supervisor, ready: Readiness,
                         timeout_s: float = READY_WITHIN_S) -> None:
        """Until every node listens (``ready.subscriptions``: the topics someone must read, of
        alternatives any one, as the composition says; the tracker the ``ready.images``
        cameras'), the bench's drivers publish (``ready.publications``: topic -> whose) and,
        with ``ready.clock``, the simulated robot's clock can be started."""
        deadline = time.monotonic() + timeout_s
        needed = [*ready.subscriptions,
                  *((f'/camera/{camera}/image_raw',) for camera in ready.images)]
        while True:
            graph.check_alive()
            missing = [' or '.join(topics) for topics in needed
                       if not any(self.node.count_subscribers(topic) for topic in topics)]
            silent = [f'{topic} ({whose})' for topic, whose in ready.publications.items()
                      if not self.node.count_publishers(topic)]
            # markers_node reads its robot's goals last of all: seen, it is listening.
            for robot in ready.markers:
                goals = namespaced_topic(robot, GOAL_TOPIC)
                if not any(info.node_name == 'markers_node' for info in
                           self.node.get_subscriptions_info_by_topic(goals)):
                    missing.append(f'(markers_node: not reading {goals} yet)')
            if ready.recording and not self.recorder.ready:
                missing.append('(the recorder: not matched to every publisher, or no driver '
                               'frame written, yet)')
            if not missing and not silent and \
                    (not ready.clock or self.parameters.service_is_ready()):
                break
            if time.monotonic() > deadline:
                if silent and not missing:
                    raise RunFailed(f'nobody publishes {", ".join(silent)} in ROS_DOMAIN_ID '
                                    f'{self.domain_id} within {timeout_s:g} s: is it running, '
                                    'in this domain, with ROS_AUTOMATIC_DISCOVERY_RANGE '
                                    f'LOCALHOST?; logs in {graph.log_dir}')
                raise RunFailed(f'the graph did not come up within {timeout_s:g} s: nobody '
                                f'subscribes {missing or "(dynamics parameters service)"}; '
                                f'logs in {graph.log_dir}')
            self.spin_for(0.05)
        graph.check_alive()
        # No grace for matching to settle here (it was 0.5 s of every run): each pairing a run
        # depends on is waited for by name (dynamics_node's awaited readers before its clock
        # runs, the goal's readers before it goes, a node's latched status once the recorder's
        # reader matched).
        self.respawns.note_endpoints_at_start()

    def send_goal(self, graph: Supervisor, goal_m: tuple[float, float], timeout_s: float = 30.0,
                  stamp_s: float = 0.0, acked_within_s: float = GOAL_READERS_MATCH_S) -> None:
        """Hand the goal to the controller while the clock stands at 0, and wait until it has
        accepted it: timer2 then counts from t = 0 whatever the wall-clock start-up took, and the
        goal is on /goal_pose for a recorder to keep. It is stamped ``stamp_s`` (the first goal
        0, a later one its predecessor's outcome): where a bag and the markers place it.

        Every reader of /goal_pose has it before this returns (DDS acknowledged it), so that
        markers_node draws it in the same array every run, whatever the machine's load."""
        if len(self.goal_publishers) != 1:
            raise RunFailed('this orchestration drives a fleet: its goals go to each robot '
                            '(FleetCoordinator.give)')
        publisher = self.goal_publishers[0]
        deadline = time.monotonic() + timeout_s
        self.wait_for_goal_readers(graph, publisher, '/', self.recording, deadline, timeout_s)
        self.goal_stamp_s = stamp_s
        goal = goal_pose(goal_m, stamp_s)
        seen = len(self.statuses)
        publisher.publish(goal)
        publisher.wait_for_all_acked(Duration(seconds=acked_within_s))
        self.goal_sent_at = seen
        resend_at = time.monotonic() + 2.0
        while True:
            graph.check_alive()
            answered = any(status['message'] in ('settling', 'goal rejected')
                           for _, status in self.statuses[seen:])
            if time.monotonic() > resend_at and not answered:
                # A reader of a node that just died can still count as matched for a moment:
                # if nobody acknowledged, the goal went there. Say it again.
                publisher.publish(goal)
                resend_at = time.monotonic() + 2.0
            for _, status in self.statuses[seen:]:
                if status['message'] == 'goal rejected':
                    raise UsageError(f'controller_node rejected the goal: {status["reason"]}')
                if status['message'] == 'settling':
                    return
            if time.monotonic() > deadline:
                raise RunFailed('controller_node did not acknowledge the goal')
            self.spin_for(0.05)

    def wait_for_goal_readers(self, graph: Supervisor, publisher: Publisher, namespace: str,
                              recording: bool, deadline: float, timeout_s: float) -> None:
        """Until the goal's readers are all there and matched by ``publisher``: by name (a count
        would be reached by the recorder's or a viewer's before the controller listens) the
        controller in ``namespace``, the recorder, and the markers_node there, which draws the
        goal. A volatile reader matched after a goal was sent never gets it."""
        needed = {_full_name(namespace, 'controller_node'),
                  *((_full_name('/', 'bag_recorder'),) if recording else ()),
                  *((_full_name(namespace, 'markers_node'),) if self.markers else ())}
        topic = publisher.topic_name
        while not needed <= {_full_name(info.node_namespace, info.node_name) for info in
                             self.node.get_subscriptions_info_by_topic(topic)}:
            graph.check_alive()
            if time.monotonic() > deadline:
                raise RunFailed(f'{topic} is not read by {" and ".join(sorted(needed))} '
                                f'within {timeout_s:g} s')
            self.spin_for(0.05)
        readers_seen = time.monotonic() + GOAL_READERS_MATCH_S
        while (publisher.get_subscription_count()
               < len(self.node.get_subscriptions_info_by_topic(topic))
               and time.monotonic() < readers_seen):
            self.spin_for(0.05)   # a reader seen but not matched yet would not get it

    def set_paused(self, graph: Supervisor, paused: bool,
                   resend_s: float = SERVICE_RESEND_S) -> None:
        request = SetParameters.Request(parameters=[Parameter(
            name='paused', value=ParameterValue(type=ParameterType.PARAMETER_BOOL,
                                                bool_value=paused))])
        could_not = f'could not {"stop" if paused else "start"} the clock of dynamics_node'
        result = self.call(graph, self.parameters, request, f'{could_not}: no answer',
                           timeout_s=10.0, resend_s=resend_s)
        if not result.results[0].successful:
            raise RunFailed(f'{could_not}: {result.results[0].reason}')

    def call(self, graph: Supervisor, client: Client, request: Any, unanswered: str,
             timeout_s: float = 30.0, resend_s: float = SERVICE_RESEND_S) -> Any:
        """``client``'s service's answer to ``request``, asked again every ``resend_s`` while
        none has come; RunFailed saying ``unanswered`` if none has within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        future = client.call_async(request)
        sent_at = time.monotonic()
        while not future.done() or future.result() is None:
            if time.monotonic() > deadline:
                raise RunFailed(f'{unanswered} within {timeout_s:g} s')
            if not client.service_is_ready():
                # The server's node is gone (one that refused its parameters dies just after it
                # was seen): its death is the message (exit 2 for a refusal), not the request.
                graph.check_alive()
            elif time.monotonic() - sent_at >= resend_s:
                # A server sees a new client's request reader before its own response writer
                # has matched the client's response reader: an answer sent in between is lost.
                # Asking again is harmless: the same value twice changes no more than once. (A
                # goal, unlike this, is sent once, to readers already matched, each waited for
                # by name: sent again, the controller takes the second for a new goal.)
                client.remove_pending_request(future)
                future = client.call_async(request)
                sent_at = time.monotonic()
            self.executor.spin_until_future_complete(future, timeout_sec=0.05)
        return future.result()

    def wait_for_outcome(self, graph: Supervisor, timeout_s: float,
                         goal: tuple[float, float]) -> dict[str, str]:
        """The controller's outcome for ``goal``, sent last (respawning nodes on the way)."""
        deadline = time.monotonic() + timeout_s
        while True:
            # A dead node is the cause, whatever the controller concluded since.
            restarted = graph.check_alive()
            self.recorder.check()
            if restarted:
                self.respawns.bring_back(graph, restarted, {0: goal}, self.goal_sent_at)
            self.respawns.watch_new_cameras(graph, {0: goal})
            for _, status in self.statuses[self.goal_sent_at:]:
                if ends_a_goal(status):
                    return dict(status, outcome=status['message'])
            if time.monotonic() > deadline:
                raise RunFailed(f'no outcome from controller_node within {timeout_s:g} s of '
                                f'wall time ({self._robot_time_said()}); logs in '
                                f'{graph.log_dir}')
            self.spin_for(0.05)

    def give_again(self, graph: Supervisor, robot: int, goal: Any) -> None:
        """The goal (x, y) m again, stamped as before (a respawned node's robot's, robot 0; a
        fleet's coordinator gives a leg: FleetCoordinator)."""
        self.send_goal(graph, goal, stamp_s=self.goal_stamp_s, acked_within_s=GOAL_ACKED_WITHIN_S)

    def simulated_time_s(self) -> float | None:
        """The robot's time as its odometry last said (the orchestration reads one tick in
        five at least)."""
        return self.latest_odometry[0] if self.latest_odometry else None

    def _robot_time_said(self) -> str:
        """Where the robot's time stands now, read from /odom, for a message."""
        if self.latest_odometry is None:
            return 'the robot published no /odom'
        return f"the robot's time reached {self.latest_odometry[0]:.2f} s"

    def wait_for_odometry_after(self, graph: Supervisor, stamp_s: float,
                                timeout_s: float) -> tuple[float, float, float, float]:
        """The first /odom sample stamped at or after ``stamp_s`` (time, x, y, heading)."""
        deadline = time.monotonic() + timeout_s
        while self.latest_odometry is None or self.latest_odometry[0] < stamp_s:
            graph.check_alive()
            if time.monotonic() > deadline:
                raise RunFailed(f'no odometry at or after t={stamp_s:.3f} s from dynamics_node')
            self.spin_for(0.05)
        return first_sample_at_or_after(self.odometry, stamp_s)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def first_sample_at_or_after(samples: deque[tuple[float, float, float, float]],
                             stamp_s: float) -> tuple[float, float, float, float]:
    """The first of ``samples`` (oldest first, by stamp) at or after ``stamp_s``, known to be the
    first only if the one before it is kept too: a later one would be a number that depends on
    when this process read it."""
    for index, sample in enumerate(samples):
        if sample[0] >= stamp_s:
            if index == 0 and len(samples) == samples.maxlen:
                break
            return sample
    raise RunFailed(f'the odometry sample at t={stamp_s:.3f} s is no longer kept (the last '
                    f'{samples.maxlen} are, from t={samples[0][0]:.3f} s): the orchestration '
                    'fell that far behind the robot')


def _full_name(namespace: str, name: str) -> str:
    return f'{namespace.rstrip("/")}/{name}'
