"""ROS 2 adapter of the slip dynamics: the simulated robot and the source of /clock.

Publishes, once per grid period of simulated time (``publish_period_s``):
  /clock          rosgraph_msgs/Clock
  /odom           nav_msgs/Odometry, odom -> base_link, twist in base_link (REP-103/105)
  /joint_states   sensor_msgs/JointState: the wheels' actual steering angle and rate, wheel
                  rotations and spin speeds
  /wheel_slip     sensor_msgs/JointState: ``wheel_<k>_longitudinal`` and ``wheel_<k>_transverse``
                  slip velocities of each contact (m/s) in ``velocity``, on one period in
                  ``wheel_slip_every`` (5 by default; nothing in the loop reads it)
  /odom_throttle, /joint_states_throttle
                  the same messages as /odom and /joint_states on one period in
                  ``throttle_every`` (5 by default): for who only watches (markers_node), to
                  whom every tick would be a delivery it does not need (topic_tools throttle's
                  names, so that a real robot's driver can be throttled the same way)
With several robots (``robots``: a fleet), each robot's streams and commands are under
its namespace (omni_micro_sim.simulated_robots), /clock is one for all, and
  /robot_contacts diagnostic_msgs/DiagnosticStatus, latched: two robots' chassis discs
                  touching (``robots``: both, ``time_s``, ``gap_m``), once per pair
Subscribes:
  /wheel_trajectory  trajectory_msgs/JointTrajectory (contract in omni_micro_sim.wheel_trajectory)

Time is owned here and paced by a wall timer at ``real_time_factor`` (``.inf``: as fast as the
graph allows; the node itself never uses sim time). While ``paused`` is true the clock stands
still, which lets an orchestrator bring the whole graph up before time 0 moves. Stamps count
from 0 (``stamp_origin: zero``), or from the wall clock at the moment time starts
(``stamp_origin: wall``, at a real-time factor of 1: what a real camera or controller beside
this simulated robot stamps with). A trajectory stamped on another clock is refused, naming
both (:mod:`omni_micro_common.clocks`).

Lockstep (``lockstep_nodes``, see :mod:`omni_micro_common.lockstep`): simulated time goes no
further than the reports on /lockstep of the named nodes allow, so a busy machine slows a run
down but never changes it. An empty list (the default for a node started alone) runs free, as
a real camera driver that does not report would need.

Time starts (and resumes) only once this node's publishers have matched the readers that must
not miss a sample (a reliable, volatile reader matched later loses what came before; that node
would then never report it, or a bag would lack it). ``awaited_readers`` names them as
``NODE:TOPIC`` (the bringup knows who reads what: ``vision_node:/odom``, ...); none by default.
"""

from __future__ import annotations

import math
import time
from typing import Any

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rcl_interfaces.msg import SetParametersResult
from rclpy.clock import Clock as RclpyClock
from rclpy.clock import ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from trajectory_msgs.msg import JointTrajectory

from omni_micro_common.clocks import clock_mismatch
from omni_micro_common.conventions import (
    join_stamp,
    split_stamp,
    stamp_ns,
)
from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import ACK_TOPIC
from omni_micro_common.lockstep_groups import LockstepGroups
from omni_micro_common.lockstep_reporting import LOCKSTEP_QOS, decode_ack_bytes
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.publication_counts import PublicationCounter
from omni_micro_common.qos import (
    DATA_QOS,
    PER_TICK_PUBLISHER_EVENTS,
    PER_TICK_SUBSCRIPTION_EVENTS,
    STATUS_QOS,
)
from omni_micro_common.reader_matching import missing_readers_report, unmatched_readers
from omni_micro_common.tick_messages import tick_templates
from omni_micro_common.topic_names import (
    CLOCK_TOPIC,
    CONTACT_TOPIC,
)
from omni_micro_sim.dynamics_parameters import checked_rtf, declare_dynamics_parameters
from omni_micro_sim.errors import CommandError, ParameterError, SimulationError
from omni_micro_sim.simulated_robots import SimulatedRobot, touching
from omni_micro_sim.state import RobotState
from omni_micro_sim.stepper import GridSimulator, Sample
from omni_micro_sim.wheel_trajectory import (
    TrajectoryPoint,
    command_from_points,
)

# With no lockstep and an unbounded factor the timer would spin; with lockstep, reports drive
# time and the timer only restarts it after a pause.
_KICK_PERIOD_S = 0.01


def stamp_seconds(stamp: Time) -> float:
    return join_stamp(stamp.sec, stamp.nanosec)


# Wall seconds of simulated time standing still (unpaused) before the node says what it waits for.
STALL_REPORT_S = 5.0


class DynamicsNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options (context, parameter_overrides, ...) as rclpy's Node takes them: tests
        # build the node in-process with them.
        super().__init__('dynamics_node', **node_options)
        # Raises ParameterError naming the value: main() reports it and exits non-zero.
        settings = declare_dynamics_parameters(self)
        period = settings.period_s
        self.slip_every, self.throttle_every = settings.slip_every, settings.throttle_every
        self.odom_frame, self.base_frame = settings.odom_frame, settings.base_frame
        self.real_time_factor = settings.real_time_factor
        self.stamp_origin = settings.stamp_origin
        # What a stamp adds to simulated time (set when time starts, with stamp_origin wall).
        self._origin_ns = 0
        self.paused = settings.paused
        # The readers time waits for at its start, by node (see the module docstring).
        self.awaited_readers = settings.awaited_readers
        # One robot under the graph's names, or each of a fleet's under its namespace.
        namespaces = settings.robots or ['']
        poses = settings.robot_poses or [settings.initial_pose]
        models = settings.robot_models or [settings.robot]
        grids = [GridSimulator(model, period_s=period, limits=settings.limits,
                               state=RobotState(x_m=pose[0], y_m=pose[1], phi_rad=pose[2]))
                 for model, pose in zip(models, poses, strict=True)]
        grids[0].load_kernels()
        # Every robot is on this grid's ticks (one clock).
        self.grid = grids[0]
        try:
            self.lockstep = LockstepGroups(namespaces, settings.lockstep_nodes,
                                           round(period * 1e9),
                                           round(float(settings.max_lead_s) * 1e9))
        except (LockstepError, TypeError, ValueError) as error:
            raise ParameterError(f'lockstep_max_lead_s: {error}') from None
        if math.isinf(self.real_time_factor) and not self.lockstep.enabled:
            raise ParameterError('real_time_factor .inf needs lockstep_nodes: running free, '
                                 'the other nodes could not keep up with an unbounded clock')
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.publication_counter = PublicationCounter()
        count = self.publication_counter.wrap

        def per_tick(msg_type: type, topic: str) -> Any:
            return count(self.create_publisher(msg_type, topic, DATA_QOS,
                                               event_callbacks=PER_TICK_PUBLISHER_EVENTS))

        # Serialized once and patched in place each tick: converting a Python message to C
        # cost more than everything else the node does per tick (an Odometry: 74 us against
        # 5 us). The bytes are what serialize_message gives (tests/nodes).
        self._clock_template = tick_templates(self.odom_frame, self.base_frame).clock
        self.clock_pub = per_tick(Clock, CLOCK_TOPIC)
        self.robots = [SimulatedRobot(self, namespace, grid, self.odom_frame, self.base_frame,
                                      per_tick, self._on_trajectory)
                       for namespace, grid in zip(namespaces, grids, strict=True)]
        # Two robots' chassis touching: said once per pair, latched, both named (a graph of one
        # robot has no such topic).
        self.contact_pub = (self.create_publisher(DiagnosticStatus, CONTACT_TOPIC, STATUS_QOS)
                            if len(self.robots) > 1 else None)
        self._touching: set[tuple[str, str]] = set()
        self._publishers_of = {pub.topic_name: pub for pub in (
            self.clock_pub, *(pub for robot in self.robots for pub in robot.publishers))}
        for node, topics in self.awaited_readers.items():
            unknown = [topic for topic in topics if topic not in self._publishers_of]
            if unknown:
                raise ParameterError(f'awaited_readers: {node} reads {unknown}, which this '
                                     f'node does not publish ({sorted(self._publishers_of)})')
        # Each awaited reader as reader_matching takes it: the publisher, the node beside it.
        self._awaited_writers = [(self._publishers_of[topic], [node]) for node, topics
                                 in self.awaited_readers.items() for topic in topics]
        # Time starts (and resumes) only once the awaited readers are matched.
        self._readers_pending = True
        if self.lockstep.enabled:
            self.create_subscription(DiagnosticStatus, ACK_TOPIC, self._on_ack, LOCKSTEP_QOS,
                                     raw=True,
                                     event_callbacks=PER_TICK_SUBSCRIPTION_EVENTS)
        self._wall_origin = time.monotonic()
        self._tick_origin = 0
        self._timer = self.create_timer(self._timer_period(), self._on_timer)
        # A graph whose time stands still says why, on the wall clock (simulated time is what
        # stands still): which node, report or command the lockstep waits for.
        self._stalled_since: tuple[int, float] = (self.grid.tick, time.monotonic())
        self.create_timer(STALL_REPORT_S, self._report_stall,
                          clock=RclpyClock(clock_type=ClockType.STEADY_TIME))
        self.get_logger().info(
            f'robot ready: grid {period * 1e3:g} ms, real-time factor '
            f'{self.real_time_factor:g}, '
            + (f'{len(self.robots)} robots ({", ".join(settings.robots)}), '
               if settings.robots else '')
            + (f'lockstep with {list(self.lockstep.nodes)}' if self.lockstep.enabled
               else 'free-running') + (', paused' if self.paused else ''))

    # -- parameters --------------------------------------------------------------------------
    def _on_set_parameters(self, params: list) -> SetParametersResult:
        changes: dict[str, Any] = {}
        for param in params:
            if param.name == 'real_time_factor':
                try:
                    changes['rtf'] = checked_rtf(param.value)
                except ParameterError as error:
                    return SetParametersResult(successful=False, reason=str(error))
                if math.isinf(changes['rtf']) and not self.lockstep.enabled:
                    return SetParametersResult(
                        successful=False, reason='real_time_factor .inf needs lockstep_nodes')
            elif param.name == 'paused':
                if not isinstance(param.value, bool):
                    return SetParametersResult(
                        successful=False, reason=f'paused must be a bool, got {param.value!r}')
                changes['paused'] = param.value
        if 'rtf' in changes:
            self.real_time_factor = changes['rtf']
        if 'paused' in changes:
            if self.stamp_origin == 'wall' and changes.get('rtf', 1.0) != 1.0:
                return SetParametersResult(successful=False,
                                           reason='stamp_origin wall runs at real_time_factor 1')
            if self.paused and not changes['paused']:
                self._readers_pending = True
                # A node may have been replaced while time stood still: a new process knows
                # nothing of its predecessor's reports, so everyone starts level from here.
                self.lockstep.reset(self.grid.tick * self._period_ns)
            self.paused = changes['paused']
        # Pacing restarts from here, so a pause or a new factor never makes time jump.
        self._wall_origin = time.monotonic()
        self._tick_origin = self.grid.tick
        if 'rtf' in changes:
            self._timer.cancel()
            self._timer = self.create_timer(self._timer_period(), self._on_timer)
        return SetParametersResult(successful=True)

    def _timer_period(self) -> float:
        if math.isinf(self.real_time_factor):
            return _KICK_PERIOD_S
        # Beyond ~2 kHz of callbacks Python spends its time in the executor: catch up instead.
        return max(self.grid.period_s / self.real_time_factor, 5e-4)

    @property
    def _period_ns(self) -> int:
        return self.lockstep.period_ns

    # -- time --------------------------------------------------------------------------------
    def _on_timer(self) -> None:
        self._advance()

    def _report_stall(self) -> None:
        tick, since = self._stalled_since
        if self.paused or tick != self.grid.tick:
            self._stalled_since = (self.grid.tick, time.monotonic())
            return
        if time.monotonic() - since >= STALL_REPORT_S and self.lockstep.enabled:
            self.get_logger().warning(
                f'simulated time has stood at {self.grid.time_s:.3f} s for '
                f'{time.monotonic() - since:.0f} s: the lockstep waits for '
                f'{self._waiting_for()}')

    def _waiting_for(self) -> str:
        missing = missing_readers_report(self, self._awaited_writers) \
            if self._readers_pending else ''
        if missing:
            return 'matching ' + missing
        return self.lockstep.waiting_for() or 'nothing (the wall clock paces it)'

    def _on_ack(self, data: bytes) -> None:
        try:
            ack = decode_ack_bytes(data)
        except LockstepError as error:
            self.get_logger().error(f'ignored: {error}', throttle_duration_sec=5.0)
            return
        if ack is not None:
            self.lockstep.on_ack(ack)
        self._advance()

    def _due_tick(self) -> int | float:
        """The last tick the wall clock allows at the real-time factor."""
        if math.isinf(self.real_time_factor):
            return math.inf
        elapsed = (time.monotonic() - self._wall_origin) * self.real_time_factor
        return self._tick_origin + int(elapsed / self.grid.period_s)

    def _unmatched_readers(self) -> list[str]:
        """The awaited readers (``awaited_readers``) this node's publishers have not matched
        yet."""
        return [missing for publisher, names in self._awaited_writers
                for missing in unmatched_readers(self, publisher, names)]

    def _advance(self) -> None:
        if self.paused:
            return   # the clock was published when it stopped; repeats would only vary bags
        if self._readers_pending:
            if self._unmatched_readers():
                return
            self._readers_pending = False
            # Pacing starts from here: the wait for readers is not simulated time.
            self._wall_origin = time.monotonic()
            self._tick_origin = self.grid.tick
            if self.stamp_origin == 'wall' and not self._origin_ns:
                # The current tick is now on the wall clock, and every later one follows it.
                self._origin_ns = time.time_ns() - round(self.grid.time_s * 1e9)
        due = self._due_tick()
        if self.lockstep.enabled:
            reachable = self.lockstep.reachable_ns()   # whole ns, as the nodes' stamps
            due = min(due, reachable // self._period_ns if math.isfinite(reachable)
                      else reachable)
        # Never more than 50 periods per callback: if the machine cannot keep up, simulated time
        # slows down rather than the node starving its subscriptions.
        # (-inf: the lockstep holds time still, a command being on its way.)
        steps = 0 if due == -math.inf else int(min(due - self.grid.tick, 50))
        for _ in range(steps):
            try:
                samples = [robot.grid.advance() for robot in self.robots]
            except SimulationError as error:
                self.get_logger().error(f'{error}; stopping the robots')
                for robot in self.robots:
                    robot.grid.schedule_stop()
                return
            self._publish(samples)
            if len(samples) > 1:
                self._report_contacts(samples)
        if self._due_tick() - self.grid.tick > 200 and not math.isinf(self.real_time_factor):
            # Far behind the wall clock (held by the lockstep, or a busy machine): pace again
            # from here instead of racing to catch up.
            self._wall_origin = time.monotonic()
            self._tick_origin = self.grid.tick

    def _stamp(self, time_s: float) -> tuple[int, int]:
        """Simulated time as the messages carry it (from 0, or on the wall clock)."""
        if not self._origin_ns:
            return split_stamp(time_s)
        return divmod(self._origin_ns + round(time_s * 1e9), 1_000_000_000)

    def _publish(self, samples: list[Sample]) -> None:
        sec, nanosec = self._stamp(samples[0].time_s)
        self.clock_pub.publish(self._clock_template.encode((sec, nanosec)))
        tick = self.grid.tick
        for robot, sample in zip(self.robots, samples, strict=True):
            robot.publish(sample, sec, nanosec, throttle=tick % self.throttle_every == 0,
                          slip=tick % self.slip_every == 0)

    def _report_contacts(self, samples: list[Sample]) -> None:
        for a, b, gap in touching(self.robots, samples):
            if (a.namespace, b.namespace) in self._touching:
                continue
            self._touching.add((a.namespace, b.namespace))
            assert self.contact_pub is not None   # touching needs two robots
            self.get_logger().error(f'{a.namespace} and {b.namespace} touch at '
                                    f'{samples[0].time_s:.3f} s: centres {gap * 1e3:.3f} mm apart')
            self.contact_pub.publish(DiagnosticStatus(
                level=DiagnosticStatus.ERROR, name='dynamics_node', message='contact',
                values=[KeyValue(key='robots', value=f'{a.namespace},{b.namespace}'),
                        KeyValue(key='time_s', value=repr(samples[0].time_s)),
                        KeyValue(key='gap_m', value=repr(gap))]))

    # -- commands ----------------------------------------------------------------------------
    def _on_trajectory(self, robot: SimulatedRobot, msg: JointTrajectory) -> None:
        self._schedule_trajectory(robot, msg)
        if self.lockstep.enabled:
            self._advance()   # time may have been waiting for this very command

    def _schedule_trajectory(self, robot: SimulatedRobot, msg: JointTrajectory) -> None:
        stamp = stamp_ns(msg.header.stamp) - self._origin_ns
        self.lockstep.on_command(robot.namespace, stamp)
        grid = robot.grid
        mismatch = clock_mismatch('a /wheel_trajectory', stamp_seconds(msg.header.stamp),
                                  'this robot', join_stamp(*self._stamp(grid.time_s)))
        if mismatch is not None and msg.points:
            self.get_logger().error(f'rejected: {mismatch}; the robot stays as it is',
                                    throttle_duration_sec=1.0)
            return
        points = [TrajectoryPoint(p.time_from_start.sec + p.time_from_start.nanosec * 1e-9,
                                  list(p.positions), list(p.velocities)) for p in msg.points]
        try:
            start_s = join_stamp(*divmod(stamp, 1_000_000_000))
            command = command_from_points(msg.joint_names, points, start_s,
                                          grid.time_s, grid.limits)
            scheduled = grid.schedule(command)
        except CommandError as error:
            self.get_logger().error(f'rejected wheel trajectory: {error}; stopping '
                                    f'{robot.label}')
            grid.schedule_stop()
            return
        if command.is_stop:
            self.get_logger().info(f'stop at t={scheduled.start_s:.3f} s'
                                   + (f' ({robot.namespace})' if robot.namespace else ''))
            return
        if scheduled.late_by_s > 0.0:
            self.get_logger().warning(
                (f'{robot.namespace}: ' if robot.namespace else '')
                + f'wheel trajectory arrived {scheduled.late_by_s:.3f} s (simulated) after its '
                f'start stamp; it runs in full from t={scheduled.start_s:.3f} s')


COMPONENT = NodeComponent(DynamicsNode, config_errors=(ParameterError, CommandError))


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
