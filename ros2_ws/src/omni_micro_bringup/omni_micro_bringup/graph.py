"""Orchestration of the node graph (what a launch file would do, launch being unavailable here).

One run sequence for one robot or several (:func:`run_graph`): the graph checked, started with
the clock paused so that nothing moves before every node listens (what each robot's nodes, the
bench's drivers and the recorder must show: :mod:`.readiness`, for 1..N robots alike), driven (a
single robot's goals, :mod:`.goal_sequence`, or a fleet's legs, :mod:`.fleet_dispatch`), the
recorder's tail waited for, and stopped in phases (the controller, then the rest at once, then
the recorder; SIGINT, and SIGTERM / SIGKILL only for a node that hangs), Fast DDS shared-memory
leftovers cleaned. Each node is its own OS process through its installed entry point (or one
container for the loop), on loopback only and in a private DDS domain; their logs are kept and
prefixed.

The children cannot outlive it: each inherits the read end of a lifeline pipe whose write end
only this process holds (when it dies, however it dies, every node reads end-of-file and stops),
and the lock file of the run's DDS domain, so that the domain is not handed to another run while
any process of this one is still in it.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

from omni_micro_bringup.errors import RunFailed, UsageError
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.graph_result import GraphResult
from omni_micro_bringup.node_overrides import wired_specs
from omni_micro_bringup.node_spec import NodeSpec, process_argv
from omni_micro_bringup.processes import (
    DomainLease,
    NodeProcess,
    new_log_dir,
    node_environment,
    prepare_node_starts,
    resident_memory_kb,
    stop_together,
)
from omni_micro_bringup.readiness import readiness
from omni_micro_bringup.shared_memory import (
    clean_shared_memory,
    left_shared_memory,
    shared_memory_files_in_use,
    shared_memory_identities,
)
from omni_micro_common.conventions import LIFELINE_ENV, PUBLISHED_MARKER
from omni_micro_common.errors import OmniMicroError

if TYPE_CHECKING:   # rclpy only where a graph runs: `omni-micro run --help` loads none of it
    from omni_micro_bringup.orchestrator import Orchestrator

# Stopped phase by phase, each phase at once: the controller first (its stop command is its last
# word), the recorder last (it keeps the stop and the final samples); anyone else in between.
SHUTDOWN_PHASES = (('controller_node',), None, ('bag_recorder',))
# How long the recorder may take to finish its bag once asked to stop (then SIGTERM; a bag
# left unfinished is recovered: in the same order, without its last second).
RECORDER_FINISH_S = 120.0


class Graph:
    """The running processes of one graph, stopped in order however the run ends."""

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
        specs = wired_specs(options) if specs is None else specs
        if options.respawn:
            specs = [replace(spec, respawn=True) if spec.respawnable else spec
                     for spec in specs]
        self.processes = [NodeProcess(spec, process_argv(spec), env,
                                      log_dir / f'{spec.name}.log', options.echo, inherited)
                          for spec in specs]
        # This graph's shared-memory files another graph's process took while it stopped.
        self.shared_memory_taken: dict[str, set[int]] = {}

    def process(self, name: str) -> NodeProcess:
        return next(p for p in self.processes if p.name == name)

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return self.process(name).wait_ready(timeout_s)

    def resident_memory_kb(self) -> dict[str, int]:
        return resident_memory_kb(self.processes)

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


class Driver(Protocol):
    """What the run sequence needs of whoever drives the robots: a single robot's goals
    (goal_sequence.GoalSequence) or a fleet's legs (fleet_dispatch.FleetDispatch)."""

    @property
    def monitor(self) -> Orchestrator | None:
        """The orchestration's node, once made (:meth:`orchestrator`)."""
        ...

    def check(self) -> None:
        """Raise UsageError for what cannot run, before anything is written."""
        ...

    def specs(self, log_dir: Path) -> list[NodeSpec]:
        """The graph's processes, each as it starts."""
        ...

    def orchestrator(self, domain_id: int, respawnable: list[str]) -> Orchestrator:
        """The orchestration's node in the run's domain, bringing back the ``respawnable``
        processes should they be respawned."""
        ...

    def drive(self, graph: Graph, on_running: Callable[[], None],
              domain_id: int) -> GraphResult:
        """From the graph ready (readiness) to the run's end and its bag's tail, the clock
        started on the way (``on_running`` called then)."""
        ...

    def close(self, log_dir: Path) -> None:
        """What it keeps beside the logs, however the run ended."""
        ...


def run_graph(options: GraphOptions,
              on_running: Callable[[Graph], None] | None = None) -> GraphResult:
    """Run the graph to its end: a single robot's controller's outcome with the true final
    pose, or (``options.fleet``) every robot's tasks done, one lost or two touching. The one
    sequence for both: checked, started, ready, driven with the clock started, the recorder's
    tail, stopped. ``on_running`` is called with the Graph once the clock runs (tests kill a
    node with it).

    Raises
    ------
    UsageError
        A bad params file, an existing bag path, or a node refusing its parameters.
    RunFailed
        If a node died, the graph did not come up, or no outcome came within the timeout; the
        message names the node and where its log is.
    """
    driver = driver_for(options)
    with brought_up(options, driver) as (graph, domain_id):
        def running() -> None:
            if on_running is not None:
                on_running(graph)

        result = driver.drive(graph, running, domain_id)
    goals = driver.monitor.goals_published.counts if driver.monitor else {}
    result.published = {**graph.published(), **goals}
    result.respawns = {p.name: p.starts - 1 for p in graph.processes if p.starts > 1}
    return result


def driver_for(options: GraphOptions) -> Driver:
    """Who drives the graph of ``options``: a fleet's legs (``options.fleet``) or a single
    robot's goals."""
    from omni_micro_bringup.fleet_dispatch import FleetDispatch
    from omni_micro_bringup.goal_sequence import GoalSequence

    return FleetDispatch(options) if options.fleet else GoalSequence(options)


@contextmanager
def brought_up(options: GraphOptions, driver: Driver) -> Iterator[tuple[Graph, int]]:
    """The graph of ``driver``'s processes started in the run's domain (leased, or the
    drivers' joined) with the orchestration's node, and ready as readiness says (its clock still
    paused), then stopped in phases however the block ends; what cannot run is refused before
    anything is written."""
    driver.check()
    if options.record is not None:
        from omni_micro_tools.bags import check_bag_output

        check_bag_output(options.record, options.force)
    prepare_node_starts(options.log_dir)
    log_dir = new_log_dir(options.log_dir)
    # With external parts the domain is the drivers': joined, not leased.
    lease = DomainLease(options.domain_id, joined=options.external)
    with lease as domain_id:
        graph = Graph(options, domain_id, log_dir, lease.fileno, specs=driver.specs(log_dir))
        monitor = driver.orchestrator(
            domain_id, [process.name for process in graph.processes if process.spec.respawn])
        try:
            graph.start()
            monitor.wait_until_ready(graph, readiness(options))
            yield graph, domain_id
        finally:
            driver.close(log_dir)
            monitor.close()
            graph.stop()
