"""Orchestration of the node graph (what a launch file would do, launch being unavailable here).

Starts each node as its own OS process through its installed entry point, with its package's
params file, on loopback only and in a private DDS domain; keeps and prefixes their logs; brings
the graph up with the clock paused so that nothing moves before every node listens; waits for the
controller's outcome; shuts down in phases (the controller, then the rest at once, then the
recorder; SIGINT, and SIGTERM / SIGKILL only for a node that hangs) and cleans Fast DDS
shared-memory leftovers.

The children cannot outlive it: each inherits the read end of a lifeline pipe whose write end
only this process holds (when it dies, however it dies, every node reads end-of-file and stops),
and the lock file of the run's DDS domain, so that the domain is not handed to another run while
any process of this one is still in it.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from omni_micro_bringup.composition import (
    GRAPH_NODE_NAMES,
    OPTIONAL_NODE_NAMES,
    GraphOptions,
    NodeSpec,
    all_specs,
    bench_cameras,
    servo_mode,
    streaming_cameras,
)
from omni_micro_bringup.errors import RunFailed, UsageError
from omni_micro_bringup.node_overrides import node_overrides
from omni_micro_bringup.params_files import (
    check_params_file,
    format_parameter,
    graph_params_file,
    resolve_executable,
)
from omni_micro_bringup.processes import (
    DomainLease,
    NodeProcess,
    new_log_dir,
    node_environment,
    prepare_node_starts,
    resident_memory_kb,
    stop_together,
)
from omni_micro_bringup.readiness import (
    external_publications,
    ready_subscriptions,
    simulates_robot,
)
from omni_micro_bringup.shared_memory import (
    clean_shared_memory,
    left_shared_memory,
    shared_memory_files_in_use,
    shared_memory_identities,
)
from omni_micro_common.conventions import LIFELINE_ENV, PUBLISHED_MARKER, STATUS_TIME_KEY
from omni_micro_common.errors import OmniMicroError
from omni_micro_common.topic_names import GOAL_TOPIC

# Stopped phase by phase, each phase at once: the controller first (its stop command is its last
# word), the recorder last (it keeps the stop and the final samples); anyone else in between.
SHUTDOWN_PHASES = (('controller_node',), None, ('bag_recorder',))
# How long the recorder may take to finish its bag once asked to stop (then SIGTERM; a bag
# left unfinished is recovered: in the same order, without its last second).
RECORDER_FINISH_S = 120.0
# How long a run on the bench waits for the robot's first state and the cameras' first frames
# (bench_start), as for the drivers' topics.
BENCH_READY_S = 60.0
# A recorded run goes on this far (simulated time) past the bag's end before it is stopped:
# markers_node draws an array once the odometry is two arrays (0.2 s) past it.
RUN_ON_PAST_BAG_END_S = 0.4


@dataclass
class GraphResult:
    outcome: str
    reason: str
    periods: int
    final_x_m: float
    final_y_m: float
    final_phi_rad: float
    goal_m: tuple[float, float]
    sim_time_s: float
    wall_time_s: float
    log_dir: Path
    domain_id: int
    status: dict[str, str]
    route: list[tuple[float, float, float]] = field(default_factory=list)       # t, x, y
    captures: list[tuple[float, float, float, str]] = field(default_factory=list)  # t, x, y, cam
    goals: list[dict[str, str]] = field(default_factory=list)   # final status of every goal
    published: dict[str, int] = field(default_factory=dict)     # per topic, all nodes
    memory_kb: dict[str, list[int]] = field(default_factory=dict)  # RSS after each goal
    respawns: dict[str, int] = field(default_factory=dict)

    @property
    def deviation_m(self) -> float:
        return math.hypot(self.final_x_m - self.goal_m[0], self.final_y_m - self.goal_m[1])

    def as_json(self) -> dict[str, object]:
        return {
            'outcome': self.outcome, 'reason': self.reason, 'periods': self.periods,
            'final_x_mm': self.final_x_m * 1e3, 'final_y_mm': self.final_y_m * 1e3,
            'final_phi_deg': math.degrees(self.final_phi_rad),
            'deviation_mm': self.deviation_m * 1e3,
            'goal_x_mm': self.goal_m[0] * 1e3, 'goal_y_mm': self.goal_m[1] * 1e3,
            'sim_time_s': self.sim_time_s, 'wall_time_s': self.wall_time_s,
            'real_time_factor': (self.sim_time_s / self.wall_time_s
                                 if self.wall_time_s > 0 else None),
            'log_dir': str(self.log_dir), 'domain_id': self.domain_id,
        }


def _argv(spec: NodeSpec, options: GraphOptions) -> list[str]:
    if spec.command is not None:
        return list(spec.command)
    executable = str(resolve_executable(spec.package, spec.executable))
    if spec.hosts:
        # The container's command line: each node's module, then its own arguments up to --.
        return [executable, *(word for hosted in spec.hosts for word in (
            f'{hosted.package}.{hosted.executable}', *_ros_args(hosted, options), '--'))]
    return [executable, *_ros_args(spec, options)]


def _ros_args(spec: NodeSpec, options: GraphOptions) -> list[str]:
    """A node's ROS arguments: its package's params file, the user's, the run's overrides."""
    argv = ['--ros-args', '--params-file', str(graph_params_file())]
    for path in options.params_files:
        argv += ['--params-file', str(path)]
    for name, value in node_overrides(spec, options).items():
        argv += ['-p', f'{name}:={format_parameter(value)}']
    return argv


class Graph:
    """The running processes of one graph, stopped in order however the run ends."""

    RESPAWNABLE = ('vision_node', 'controller_node')

    def __init__(self, options: GraphOptions, domain_id: int, log_dir: Path,
                 lease_fd: int | None = None, specs: list[NodeSpec] | None = None) -> None:
        self.options = options
        self.domain_id = domain_id
        self.log_dir = log_dir
        env = node_environment(domain_id, log_dir)
        # Only this process holds the write end (os.pipe() fds are not inherited); the read end
        # goes to every child, which stops when it reads end-of-file.
        self._lifeline_read, self._lifeline_write = os.pipe()
        env[LIFELINE_ENV] = str(self._lifeline_read)
        inherited = (self._lifeline_read,) + (() if lease_fd is None else (lease_fd,))
        specs = all_specs(options) if specs is None else specs
        if options.respawn:
            specs = [replace(spec, respawn=True) if spec.name in self.RESPAWNABLE else spec
                     for spec in specs]
        self.processes = [NodeProcess(spec, _argv(spec, options), env,
                                      log_dir / f'{spec.name}.log', options.echo, inherited)
                          for spec in specs]
        # This graph's shared-memory files another graph's process took while it stopped.
        self.shared_memory_taken: dict[str, set[int]] = {}

    def process(self, name: str) -> NodeProcess:
        return next(p for p in self.processes if p.name == name)

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return self.process(name).wait_ready(timeout_s)

    def start(self) -> None:
        for process in self.processes:
            process.start()

    def check_alive(self) -> list[str]:
        """Restart dead nodes that respawn and return their names; raise for any other death.

        Raises
        ------
        UsageError
            A node refused its parameters (exit code 2): the message is the node's own.
        RunFailed
            A node died; the message names it and quotes the end of its log.
        """
        restarted = []
        for process in self.processes:
            code = process.exit_code()
            if code is None:
                continue
            process.join_output()
            tail = '\n  '.join(process.tail) or '(no output)'
            if code == 2 and process.starts == 1:
                raise UsageError(f'{process.name} refused its parameters:\n  {tail}')
            if process.spec.respawn:
                if self.options.echo:
                    self.options.echo(f'[orchestration] {process.name} exited with {code}; '
                                      f'respawning it')
                process.start()
                restarted.append(process.name)
                continue
            if self.options.echo:
                self.options.echo(f'[orchestration] {process.name} exited with code {code}; '
                                  f'stopping the graph')
            raise RunFailed(f'{process.name} exited with code {code} before the outcome; '
                            f'its log ({process.log_path}) ends:\n  {tail}')
        return restarted

    def _cut_lifeline(self) -> None:
        for fd in (self._lifeline_read, self._lifeline_write):
            if fd >= 0:
                os.close(fd)
        self._lifeline_read = self._lifeline_write = -1

    def stop(self) -> dict[str, int | None]:
        """Stop every node, phase by phase; returns their exit codes (-9: it needed SIGKILL)."""
        started = time.monotonic()
        pids = [p.process.pid for p in self.processes if p.process]
        used = shared_memory_identities(shared_memory_files_in_use(pids))
        named = {name for phase in SHUTDOWN_PHASES if phase for name in phase}
        codes: dict[str, int | None] = {}
        took: dict[str, float] = {}
        for phase in SHUTDOWN_PHASES:
            # Every robot's controller with the controllers.
            members = [p for p in self.processes
                       if (p.role in phase if phase else p.role not in named)]
            # The recorder finishes its bag after its signal: it reads the bag back and writes
            # it again in the order of simulated time (a gigabyte of images takes seconds).
            recorder = phase is not None and 'bag_recorder' in phase
            codes.update(stop_together(members, grace_s=RECORDER_FINISH_S if recorder else 5.0,
                                       took_s=took))
        self._cut_lifeline()
        if self.options.echo:
            slowest = max(took, key=took.__getitem__, default=None)
            self.options.echo(f'[orchestration] graph stopped in '
                              f'{time.monotonic() - started:.2f} s'
                              + (f' (the slowest, {slowest}, {took[slowest]:.2f} s after its '
                                 'signal)' if slowest else '') + '; exit codes: '
                              + ', '.join(f'{name} {code}' for name, code in codes.items()))
        # Only after a death: cleaning locks every port's lock file to test it, which another
        # graph's node starting then fails to take (docs/development.md, "The suite").
        if left_shared_memory(codes, [p.starts for p in self.processes]):
            self.shared_memory_taken = clean_shared_memory(used, pids)
            if self.shared_memory_taken and self.options.echo:
                self.options.echo('[orchestration] left in /dev/shm, taken by processes of '
                                  'another graph: ' + ', '.join(sorted(self.shared_memory_taken)))
        record = self.options.record
        if record is not None and record.is_dir() and not (record / 'metadata.yaml').exists():
            self._recover_bag(record)
        return codes

    def _recover_bag(self, bag: Path) -> None:
        """The recorder died (or could not finish the bag): turn what it flushed into a readable
        bag at the same path; if that fails too (a full disk), the bag stays as it was."""
        from omni_micro_tools.bags import recover

        torn = bag.with_name(bag.name + '.torn')
        shutil.rmtree(torn, ignore_errors=True)
        bag.rename(torn)
        try:
            report = recover(torn, bag)
        except (OmniMicroError, OSError) as error:
            shutil.rmtree(bag, ignore_errors=True)
            torn.rename(bag)
            if self.options.echo:
                self.options.echo(f'[orchestration] could not recover {bag}: {error}; it stays '
                                  'as the recorder left it')
            return
        shutil.rmtree(torn)
        if self.options.echo:
            self.options.echo(f'[orchestration] the recorder died; recovered '
                              f'{report.kept} messages into {bag}')

    def published(self) -> dict[str, int]:
        """What the nodes say they published (their last log line), summed per topic."""
        totals: dict[str, int] = {}
        for process in self.processes:
            if not process.log_path.exists():
                continue
            for line in process.log_path.read_text().splitlines():
                if line.startswith(PUBLISHED_MARKER):
                    for topic, count in json.loads(line[len(PUBLISHED_MARKER):]).items():
                        totals[topic] = totals.get(topic, 0) + count
        return totals


def run_graph(options: GraphOptions,
              on_running: Callable[[Graph], None] | None = None) -> GraphResult:
    """Run the graph to the controller's outcome and return it with the true final pose.
    ``on_running`` is called with the Graph once the clock runs (tests kill a node with it).

    Raises
    ------
    UsageError
        A bad params file, an existing bag path, or a node refusing its parameters.
    RunFailed
        If a node died, the graph did not come up, or no outcome came within the timeout; the
        message names the node and where its log is.
    """
    for path in options.params_files:
        check_params_file(path, (*GRAPH_NODE_NAMES, *OPTIONAL_NODE_NAMES))
    if options.record is not None:
        from omni_micro_tools.bags import check_bag_output

        check_bag_output(options.record, options.force)
    all_specs(options)   # a graph that cannot be is refused before anything is written
    prepare_node_starts(options.log_dir)
    from omni_micro_bringup.bench_start import wait_for_bench  # rclpy only where a graph runs
    from omni_micro_bringup.orchestrator import Orchestrator
    from omni_micro_tools.topics import BAG_TAIL_S

    log_dir = new_log_dir(options.log_dir)
    goals = [(float(x), float(y)) for x, y in [options.goal_m, *options.more_goals_m]]
    # With external parts the domain is the drivers': joined, not leased.
    lease = DomainLease(options.domain_id, joined=options.external)
    with lease as domain_id:
        graph = Graph(options, domain_id, log_dir, lease.fileno)
        monitor = Orchestrator(domain_id, follow_route=options.follow_route, echo=options.echo,
                               markers=options.markers)
        recording = options.record is not None
        statuses = []
        memory: dict[str, list[int]] = {}
        simulated_robot = simulates_robot(options)
        try:
            graph.start()
            monitor.wait_until_ready(graph, timeout_s=60.0, recording=recording,
                                     markers=options.markers,
                                     images=streaming_cameras(options),
                                     subscriptions=ready_subscriptions(options),
                                     publications=external_publications(options),
                                     clock=simulated_robot)
            if options.external:
                wait_for_bench(monitor, graph, robot=options.robot == 'external',
                               cameras=bench_cameras(options), timeout_s=BENCH_READY_S,
                               ages=servo_mode(options))
            wall_start = time.monotonic()
            # The goal at the robot's time: 0 for a simulated one, the wall clock on the bench.
            goal_stamp_s = time.time() if options.external else 0.0
            for index, goal in enumerate(goals):
                monitor.send_goal(graph, goal, recording, stamp_s=goal_stamp_s)
                if index == 0:
                    wall_start = time.monotonic()
                    if simulated_robot:
                        monitor.set_paused(graph, False)
                    if on_running is not None:
                        on_running(graph)
                status = monitor.wait_for_outcome(graph, options.timeout_s, goal, recording)
                statuses.append(status)
                goal_stamp_s = float(status.get(STATUS_TIME_KEY, goal_stamp_s))
                for name, size in resident_memory_kb(graph.processes).items():
                    memory.setdefault(name, []).append(size)
                if status['outcome'] not in ('reached', 'completed'):
                    break
            wall_time = time.monotonic() - wall_start
            capture_stamp = float(status.get('capture_stamp_s', '0'))
            if simulated_robot:
                odom = monitor.wait_for_odometry_after(graph, capture_stamp, timeout_s=30.0)
                if recording:
                    # The bag ends BAG_TAIL_S after the outcome; everything up to there, the
                    # markers' arrays included, is published before the graph stops.
                    run_to_s = goal_stamp_s + BAG_TAIL_S + RUN_ON_PAST_BAG_END_S
                    monitor.wait_for_odometry_after(graph, run_to_s, timeout_s=30.0)
                    monitor.wait_for_recorder_past(graph, run_to_s, timeout_s=60.0)
            else:
                # A real robot's true pose is nobody's to know: where the camera saw it last.
                odom = (capture_stamp, float(status.get('measured_x_m', 'nan')),
                        float(status.get('measured_y_m', 'nan')),
                        float(status.get('measured_phi_rad', 'nan')))
                if recording:
                    # The bag's tail: the stop and the robot's wheels coming to rest.
                    monitor.wait_for_recorder_past(graph, goal_stamp_s + BAG_TAIL_S,
                                                   timeout_s=60.0)
        finally:
            monitor.close()
            graph.stop()
    published = graph.published()
    published[GOAL_TOPIC] = monitor.goals_sent
    return GraphResult(
        outcome=status['outcome'], reason=status.get('reason', ''),
        periods=int(status.get('periods', '0')), final_x_m=odom[1], final_y_m=odom[2],
        final_phi_rad=odom[3], goal_m=goals[len(statuses) - 1],
        # On the wall clock (external parts) the robot's time is the wall's.
        sim_time_s=(wall_time if options.external
                    else float(status.get('sim_time_s', 'nan'))), wall_time_s=wall_time,
        log_dir=log_dir, domain_id=domain_id, status=status, route=monitor.route,
        captures=monitor.captures, goals=statuses, published=published, memory_kb=memory,
        respawns={p.name: p.starts - 1 for p in graph.processes if p.starts > 1})


