"""The orchestration's node for a fleet's run (:class:`FleetCoordinator`): it hands each robot
its goals on ``/robot_k/goal_pose``, each goal's tolerance set on that robot's controller first,
reads every robot's statuses and throttled odometry and dynamics_node's contacts, and reports
each goal's end handled in that robot's lockstep gate, as the coordinator
(:mod:`omni_micro_bringup.fleet_dispatch` drives the run with it).
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable

from diagnostic_msgs.msg import DiagnosticStatus
from nav_msgs.msg import Odometry
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters

from omni_micro_bringup.composition import coordinator_name
from omni_micro_bringup.errors import RunFailed, UsageError
from omni_micro_bringup.graph_result import RobotLog
from omni_micro_bringup.orchestrator import Orchestrator
from omni_micro_bringup.supervisor import Supervisor
from omni_micro_common.conventions import (
    join_stamp,
    quaternion_to_yaw,
)
from omni_micro_common.goal_message import goal_pose
from omni_micro_common.lockstep import Ack
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.qos import DATA_QOS, STATUS_QOS
from omni_micro_common.topic_names import (
    CONTACT_TOPIC,
    ODOM_THROTTLE_TOPIC,
    namespaced_topic,
    robot_name,
)
from omni_micro_control.fleet_legs import GoalOrder


class FleetCoordinator(Orchestrator):
    """The orchestration's node with every robot's goals, statuses and odometry, and its part
    in the lockstep (it reports as ``omni_micro_orchestration``, a coordinator)."""

    def __init__(self, domain_id: int, count: int, echo: Callable[[str], None] | None = None,
                 recording: bool = False, markers: bool = False,
                 respawnable: list[str] | None = None) -> None:
        self.robots = [RobotLog() for _ in range(count)]   # each robot's route, as followed
        super().__init__(domain_id, echo=echo, markers=markers, recording=recording,
                         namespaces=tuple(robot_name(k) for k in range(count)),
                         respawnable=respawnable)
        self.tolerance_clients = [self.node.create_client(
            SetParameters, f'/{robot_name(k)}/controller_node/set_parameters')
            for k in range(count)]
        # A coordinator per robot in the lockstep: two robots' goals can end at the same stamp,
        # and each end is held until that robot's is handled.
        self.reporters = [LockstepReporter(self.node, coordinator_name(robot_name(k)))
                          for k in range(count)]
        self.contacts: list[dict[str, str]] = []   # dynamics_node's: two chassis touching
        self.node.create_subscription(DiagnosticStatus, CONTACT_TOPIC, self._on_contact,
                                      STATUS_QOS)

    def _on_contact(self, msg: DiagnosticStatus) -> None:
        self.contacts.append({item.key: item.value for item in msg.values})

    def _follow_odometry(self, robot: int, namespace: str) -> None:
        """Each robot's throttled odometry, the whole route kept."""
        self.node.create_subscription(
            Odometry, namespaced_topic(namespace, ODOM_THROTTLE_TOPIC),
            functools.partial(self._on_robot_odometry, robot), DATA_QOS)

    def _on_robot_odometry(self, robot: int, msg: Odometry) -> None:
        pose = msg.pose.pose
        self.robots[robot].route.append((
            join_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec), pose.position.x,
            pose.position.y, quaternion_to_yaw(pose.orientation.z, pose.orientation.w)))

    def give_again(self, graph: Supervisor, robot: int, goal: GoalOrder) -> None:
        """The leg under way again, stamped with the end it follows, as before."""
        if self.echo:
            x_mm, y_mm = (v * 1e3 for v in goal.goal_m)
            self.echo(f'[orchestration] {robot_name(robot)}\'s leg to ({x_mm:g}, {y_mm:g}) mm '
                      'given again, from where it stands')
        self.give(graph, goal)

    def simulated_time_s(self) -> float | None:
        """How far the robots' time has gone, by the latest odometry of any robot."""
        stamps = [log.route[-1][0] for log in self.robots if log.route]
        return max(stamps) if stamps else None

    def report_handled(self, robot: int, outcome_ns: int) -> None:
        self.reporters[robot].report(Ack(coordinator_name(robot_name(robot)), None,
                                         outcome_handled_ns=outcome_ns))

    def set_tolerance(self, graph: Supervisor, robot: int, tolerance_m: float,
                      timeout_s: float = 30.0) -> None:
        """Set robot ``robot``'s controller to ``tolerance_m`` and wait until it has it."""
        request = SetParameters.Request(parameters=[Parameter(
            name='tolerance_m', value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE,
                                                     double_value=float(tolerance_m)))])
        result = self.call(graph, self.tolerance_clients[robot], request,
                           f'{robot_name(robot)}\'s controller_node did not take its tolerance',
                           timeout_s)
        if not result.results[0].successful:
            raise UsageError(f'{robot_name(robot)}\'s controller_node refused tolerance_m '
                             f'{tolerance_m!r}: {result.results[0].reason}')

    def give(self, graph: Supervisor, order: GoalOrder, timeout_s: float = 30.0) -> None:
        """Set the robot's controller to the order's tolerance, then hand it the goal stamped
        with the end it follows (``order.stamp_s``), and wait until it has taken it."""
        deadline = time.monotonic() + timeout_s
        self.set_tolerance(graph, order.robot, order.tolerance_m, timeout_s)
        publisher = self.goal_publishers[order.robot]
        self.wait_for_goal_readers(graph, publisher, f'/{robot_name(order.robot)}',
                                   self.recording, deadline, timeout_s)
        goal = goal_pose(order.goal_m, order.stamp_s)
        seen = len(self.statuses)
        # Unlike a single robot's goal, it does not wait for its acknowledgments: the
        # controller's status saying it took the goal, awaited below, says more.
        publisher.publish(goal)
        while True:
            for robot, status in self.statuses[seen:]:
                if robot != order.robot:
                    continue
                if status['message'] == 'goal rejected':
                    raise UsageError(f'{robot_name(robot)}\'s controller_node rejected the goal '
                                     f'{order.goal_m}: {status.get("reason")}')
                if status['message'] in ('settling', 'moving'):
                    return   # 'moving': captures that came before the goal moved it at once
            graph.check_alive()
            if time.monotonic() > deadline:
                raise RunFailed(f'{robot_name(order.robot)}\'s controller_node did not take its '
                                f'goal within {timeout_s:g} s')
            self.spin_for(0.02)

    def wait_for_routes_past(self, graph: Supervisor, stamp_s: float, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while any(not log.route or log.route[-1][0] < stamp_s for log in self.robots):
            graph.check_alive()
            if time.monotonic() > deadline:
                raise RunFailed(f'no odometry of every robot at or after t={stamp_s:.3f} s')
            self.spin_for(0.05)
