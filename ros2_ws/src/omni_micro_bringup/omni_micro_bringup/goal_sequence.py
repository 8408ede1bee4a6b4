"""A single robot's run through the graph: its goals handed one after another, each once the
last is reached, the clock started with the first; its true final pose read from the odometry
(a real robot's: where the camera saw it last)."""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Protocol

from omni_micro_bringup.composition import (
    GRAPH_NODE_NAMES,
    OPTIONAL_NODE_NAMES,
    bench_cameras,
    check_graph,
    servo_mode,
)
from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.graph_result import GraphResult
from omni_micro_bringup.node_overrides import wired_specs
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_bringup.orchestrator import RUN_ON_PAST_BAG_END_S, Orchestrator
from omni_micro_bringup.params_files import check_params_file
from omni_micro_bringup.readiness import (
    simulates_robot,
)
from omni_micro_bringup.supervisor import Supervisor
from omni_micro_common.conventions import STATUS_TIME_KEY


class RunningProcesses(Supervisor, Protocol):
    """What the sequence needs of the graph's processes (graph.Graph) beyond the
    orchestrator's needs: how much memory each holds after each goal (the soak's)."""

    def resident_memory_kb(self) -> dict[str, int]:
        ...


class GoalSequence:
    """The orchestration of one robot in the root namespace (``options.goal_m``, then
    ``options.more_goals_m``)."""

    def __init__(self, options: GraphOptions) -> None:
        if options.goal_m is None:
            raise UsageError('a run of one robot needs its goal: goal_m is None')
        self.options = options
        self.goals = [(float(x), float(y)) for x, y in [options.goal_m, *options.more_goals_m]]
        self.monitor: Orchestrator | None = None

    def check(self) -> None:
        """Raises UsageError for a bad params file or a graph that cannot be."""
        for path in self.options.params_files:
            check_params_file(path, (*GRAPH_NODE_NAMES, *OPTIONAL_NODE_NAMES))
        check_graph(self.options)

    def specs(self, log_dir: Path) -> list[NodeSpec]:
        return wired_specs(self.options)

    def orchestrator(self, domain_id: int, respawnable: list[str]) -> Orchestrator:
        self.monitor = Orchestrator(domain_id, follow_route=self.options.follow_route,
                                    echo=self.options.echo, markers=self.options.markers,
                                    recording=self.options.record is not None,
                                    respawnable=respawnable)
        return self.monitor

    def drive(self, graph: RunningProcesses, on_running: Callable[[], None],
              domain_id: int) -> GraphResult:
        """From the graph ready to the last goal's outcome and the bag's tail: the result,
        but for what the nodes say they published (their logs, once stopped)."""
        from omni_micro_bringup.bench_start import BENCH_READY_S, wait_for_bench
        from omni_micro_tools.topics import BAG_TAIL_S

        options, monitor = self.options, self.monitor
        assert monitor is not None
        recording = options.record is not None
        simulated_robot = simulates_robot(options)
        statuses = []
        memory: dict[str, list[int]] = {}
        if options.external:
            wait_for_bench(monitor, graph, robot=options.robot == 'external',
                           cameras=bench_cameras(options), timeout_s=BENCH_READY_S,
                           ages=servo_mode(options))
        wall_start = time.monotonic()
        # The goal at the robot's time: 0 for a simulated one, the wall clock on the bench.
        goal_stamp_s = time.time() if options.external else 0.0
        for index, goal in enumerate(self.goals):
            monitor.send_goal(graph, goal, stamp_s=goal_stamp_s)
            if index == 0:
                wall_start = time.monotonic()
                if simulated_robot:
                    monitor.set_paused(graph, False)
                on_running()
            status = monitor.wait_for_outcome(graph, options.timeout_s, goal)
            statuses.append(status)
            goal_stamp_s = float(status.get(STATUS_TIME_KEY, goal_stamp_s))
            for name, size in graph.resident_memory_kb().items():
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
                monitor.recorder.wait_past(graph, run_to_s, timeout_s=60.0)
        else:
            # A real robot's true pose is nobody's to know: where the camera saw it last.
            odom = (capture_stamp, float(status.get('measured_x_m', 'nan')),
                    float(status.get('measured_y_m', 'nan')),
                    float(status.get('measured_phi_rad', 'nan')))
            if recording:
                # The bag's tail: the stop and the robot's wheels coming to rest.
                monitor.recorder.wait_past(graph, goal_stamp_s + BAG_TAIL_S, timeout_s=60.0)
        return GraphResult(
            outcome=status['outcome'], reason=status.get('reason', ''),
            periods=int(status.get('periods', '0')), final_x_m=odom[1], final_y_m=odom[2],
            final_phi_rad=odom[3], goal_m=self.goals[len(statuses) - 1],
            # On the wall clock (external parts) the robot's time is the wall's.
            sim_time_s=(wall_time if options.external
                        else float(status.get('sim_time_s', 'nan'))), wall_time_s=wall_time,
            log_dir=graph.log_dir, domain_id=domain_id, status=status, route=monitor.route,
            captures=monitor.captures, goals=statuses, memory_kb=memory)

    def close(self, log_dir: Path) -> None:
        """Nothing of its own to leave beside the logs."""
