"""How a fleet's run is driven through the node graph (graph.run_graph with ``options.fleet``):
the robots of a fleet plan, each driven by its own controller_node on its own vision_node's
captures, one dynamics_node simulating them all.

The orchestration is the coordinator: it hands each robot its goals on ``/robot_k/goal_pose``
as :class:`~omni_micro_control.fleet_legs.LegDispatcher` says (the fleet twin's dispatcher),
each goal's tolerance set on that robot's controller first. It takes part in the lockstep: once
a controller reports the end of a goal, simulated time stands still until the coordinator has
handed out what that end allows and reported it handled, and every goal is stamped with the end
it follows (the later of the ends a leg waits for), which the controller counts from
(``goal_time: stamp``). The same plan and seed so give the same run at any speed and load.

With real robots (``options.external``: :mod:`omni_micro_bringup.fleet_bench`) nothing is in
lockstep: the robots' time is the wall clock from the first goal, each goal stamped with the
wall-clock end it follows, and the bench's guard, not dynamics_node, ends a run whose robots
would touch.
"""

from __future__ import annotations

import itertools
import json
import math
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

from std_srvs.srv import Trigger

from omni_micro_bringup.composition import (
    bench_cameras,
    check_graph,
)
from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.fleet_bench import (
    HOLD_AFTER_STOP_S,
    BenchGuard,
    check_bench,
)
from omni_micro_bringup.fleet_coordinator import FleetCoordinator
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.graph_result import GraphResult, RobotLog
from omni_micro_bringup.node_overrides import grid_period_s, wired_specs
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_bringup.orchestrator import (
    RUN_ON_PAST_BAG_END_S,
)
from omni_micro_bringup.robot_namespaces import robot_modes
from omni_micro_bringup.supervisor import RestartsNoted, Supervisor
from omni_micro_common.conventions import (
    STATUS_TIME_KEY,
)
from omni_micro_common.topic_names import (
    robot_name,
)
from omni_micro_control.feedback import OUTCOME_NAMES, REPLACED_REASON
from omni_micro_control.fleet_legs import LEG_ENDS, GoalOrder, LegDispatcher

# Stamps are whole nanoseconds: a tick's time as a float and as its stamp agree within one.
STAMP_RESOLUTION_S = 1e-9


def first_tick_past(limit_s: float, period_s: float) -> float:
    """The robots' time at which the twin stops for ``limit_s`` (its ``max_sim_time_s``): the
    first tick of its grid past it, as its stepper computes a tick's time."""
    tick = max(0, math.floor(limit_s / period_s) - 1)
    while tick * period_s <= limit_s:
        tick += 1
    return tick * period_s


class FleetDispatch:
    """The orchestration of a fleet's run (``options.fleet``): every robot handed its legs as
    the plan's dispatcher says, each end held in the lockstep until handled."""

    def __init__(self, options: GraphOptions) -> None:
        assert options.fleet is not None
        self.options = options
        self.fleet = options.fleet
        self.count = len(self.fleet.plan.starts_m)
        self.modes = robot_modes(options)
        self.monitor: FleetCoordinator | None = None
        # Real robots and their camera (options.external): no lockstep, the wall clock, and
        # the guard in place of dynamics_node's contacts.
        self.bench: BenchGuard | None = None

    def check(self) -> None:
        self.check_options(self.options)

    @staticmethod
    def check_options(options: GraphOptions) -> None:
        """Raises UsageError for a graph that cannot be (composition.check_graph) and, on the
        bench (``options.external``), for what real robots cannot do."""
        if options.external:
            check_bench(options)
        check_graph(options)

    def specs(self, log_dir: Path) -> list[NodeSpec]:
        return wired_specs(self.options, log_dir)

    def orchestrator(self, domain_id: int, respawnable: list[str]) -> FleetCoordinator:
        self.monitor = FleetCoordinator(domain_id, self.count, self.options.echo,
                                        recording=self.options.record is not None,
                                        markers=self.options.markers,
                                        respawnable=respawnable)
        if self.options.external:
            self.bench = BenchGuard(self.monitor.node, self.monitor.robots,
                                    sorted(bench_cameras(self.options)), self.fleet.stop_gap_m,
                                    self.fleet.unnamed_s)
        return self.monitor

    def drive(self, graph: Supervisor, on_running: Callable[[], None],
              domain_id: int) -> GraphResult:
        """From the graph ready to every task done (or the first robot lost, two robots
        touching, the time up) and the bag's tail."""
        from omni_micro_tools.topics import BAG_TAIL_S

        monitor, plan, options, bench = self.monitor, self.fleet.plan, self.options, self.bench
        assert monitor is not None
        graph = RestartsNoted(graph)
        logs = monitor.robots
        outcome, reason, now_s = 'done', '', 0.0
        total = sum(len(tasks) for tasks in plan.tasks)
        for log, tasks in zip(logs, plan.done_at_start, strict=True):
            log.tasks_done_s += [0.0] * len(tasks)
        if bench is None:
            for k in range(self.count):
                monitor.report_handled(k, -1)   # the coordinator takes part from here
        else:
            self.wait_for_bench(graph)
        # The robots' time 0: the wall clock's now on the bench (the stamps are its), else 0.
        origin_s = bench.origin_s if bench else 0.0
        # Simulated, the run ends where the twin's does: at the first tick past the limit, once
        # the robots' time is far enough past it that everything up to it is in (each capture
        # is handled within a controller's command lead, each end before time goes on) and the
        # bag's tail already run. What is stamped past it counts for nothing.
        limit_s = None if bench else first_tick_past(
            self.fleet.max_sim_time_s, grid_period_s(options.params_files,
                                                     options.dynamics_overrides))
        settled_s = BAG_TAIL_S + RUN_ON_PAST_BAG_END_S
        tasks_left = f'tasks left after {self.fleet.max_sim_time_s:g} s of simulated time'

        def past_limit(at_s: float) -> bool:
            return limit_s is not None and at_s > limit_s + STAMP_RESOLUTION_S
        dispatcher = LegDispatcher(plan, self.modes)
        started: dict[int, float] = {}
        driving: dict[int, GoalOrder] = {}   # each robot's leg under way

        def give(order: GoalOrder) -> None:
            order = replace(order, stamp_s=max(order.stamp_s, origin_s))
            started.setdefault(order.robot, order.stamp_s - origin_s)
            logs[order.robot].goal_poses.append((order.stamp_s - origin_s, *order.goal_m))
            driving[order.robot] = order
            monitor.give(graph, order)
            if bench:
                bench.guard.driving(order.robot, time.monotonic())

        for order in dispatcher.startable():
            give(order)
        if bench is None:
            monitor.set_paused(graph, False)
        on_running()
        wall_start = time.monotonic()
        seen = 0
        while not dispatcher.finished:
            if bench is not None and bench.stopped is not None:
                outcome, reason = 'stopped', f'every robot stopped: {bench.stopped.reason}'
                # A controller not told of the stop would go on deciding moves until the graph
                # is down (one moved a robot 6.7 mm on after a stop): each cancels its goal,
                # while the guard's timer, spun meanwhile, keeps sending stops past any move
                # decided before.
                for robot in range(self.count):
                    monitor.call(graph, bench.cancels[robot], Trigger.Request(),
                                 f'{robot_name(robot)}\'s controller_node did not cancel its '
                                 'goal', timeout_s=5.0)
                monitor.spin_for(HOLD_AFTER_STOP_S)
                bench.hand_over()
                break
            contacts = [contact for contact in monitor.contacts
                        if not past_limit(float(contact['time_s']))]
            if contacts:
                contact = contacts[0]
                a, b = contact['robots'].split(',')
                outcome = 'contact'
                reason = (f'{a} and {b} touched at {float(contact["time_s"]):.2f} s: centres '
                          f'{float(contact["gap_m"]) * 1e3:.2f} mm apart, 9 mm discs')
                break
            if time.monotonic() - wall_start > options.timeout_s:
                outcome = 'timeout'
                reason = f'tasks left after {options.timeout_s:g} s of wall time'
                break
            # On the clock, as the twin looks at it each step (not only as goals end: a robot
            # may drive for long with nothing ending).
            if bench is not None and time.time() - origin_s > self.fleet.max_sim_time_s:
                outcome, now_s = 'timeout', max(now_s, time.time() - origin_s)
                reason = tasks_left
                break
            if seen == len(monitor.statuses):
                if limit_s is not None and \
                        (monitor.simulated_time_s() or 0.0) >= limit_s + settled_s:
                    outcome, now_s = 'timeout', limit_s
                    reason = tasks_left
                    for log in logs:
                        log.route = [sample for sample in log.route if not past_limit(sample[0])]
                    break
                graph.check_alive()
                if graph.restarted:
                    # Brought back once every status read so far is handled: a leg that
                    # ended meanwhile is not given again.
                    restarted, graph.restarted = graph.restarted, []
                    monitor.respawns.bring_back(graph, restarted, driving, seen)
                    continue
                monitor.respawns.watch_new_cameras(graph, driving)
                monitor.recorder.check()
                monitor.spin_for(0.02)
                continue
            robot, status = monitor.statuses[seen]
            seen += 1
            at_s = float(status[STATUS_TIME_KEY]) - origin_s
            if past_limit(at_s):
                # The twin stops before it: an end is only said handled, so that time goes on.
                if status['message'] in OUTCOME_NAMES:
                    self.handled(robot, at_s)
                continue
            if status['message'] == 'moving':
                logs[robot].moves += 1
            if 'estimate.xi2' in status:
                logs[robot].learnt_offsets_rad = (float(status['estimate.xi2']),
                                                  float(status['estimate.xi3']))
            if status['message'] not in OUTCOME_NAMES:
                continue
            if status.get('reason') == REPLACED_REASON:
                # Not an end that gives a goal: said handled, so that time goes on.
                self.handled(robot, at_s)
                continue
            now_s = max(now_s, at_s)
            if status['message'] not in {end.value for end in LEG_ENDS}:
                outcome = 'lost'
                logs[robot].outcome = f'{status["message"]}: {status.get("reason", "")}'
                reason = f'robot {robot} {logs[robot].outcome}'
                break
            logs[robot].goal_pose_ends.append((at_s, status['message']))
            following, ended = dispatcher.reached(robot, at_s + origin_s)
            driving.pop(robot, None)
            if bench:
                bench.guard.driving(robot, time.monotonic(), driving=False)
            if following is not None:
                give(following)
            else:
                assert ended is not None
                logs[robot].legs.append((started.pop(robot), at_s, ended))
                logs[robot].tasks_done_s += [at_s] * len(ended.tasks)
                if self.fleet.on_progress is not None and ended.tasks:
                    self.fleet.on_progress(sum(len(log.tasks_done_s) for log in logs), total,
                                           at_s)
                for order in dispatcher.startable():
                    give(order)   # from the later of the ends it follows
            self.handled(robot, at_s)
        wall_time = time.monotonic() - wall_start
        if outcome == 'done':
            reason = f'every task done in {now_s:.2f} s'
            if bench is None:
                monitor.wait_for_routes_past(graph, now_s, timeout_s=30.0)
        if bench is not None:
            # The robots' controllers go at once (each stops its robot as it goes): stopped,
            # none may start a move again; the recorder goes after them, with the stops.
            return GraphResult(outcome, reason, now_s, wall_time, graph.log_dir, domain_id,
                               robots=logs, closest_gap_m=bench.guard.closest_gap_m,
                               closest_pair=bench.guard.closest_pair)
        if options.record is not None:
            # The bag ends BAG_TAIL_S after the last end: all of it received before the stop
            # (and the markers' arrays up to there drawn: they lag the odometry).
            monitor.recorder.wait_past(
                graph, now_s + BAG_TAIL_S + (RUN_ON_PAST_BAG_END_S if options.markers else 0.0),
                timeout_s=60.0)
        gap, pair = closest_approach(logs)
        return GraphResult(outcome, reason, now_s, wall_time, graph.log_dir, domain_id,
                           robots=logs, closest_gap_m=gap, closest_pair=pair)

    def handled(self, robot: int, at_s: float) -> None:
        """An end handled: said in the robot's lockstep gate (nothing real is in lockstep)."""
        if self.bench is None and self.monitor is not None:
            self.monitor.report_handled(robot, round(at_s * 1e9))

    def wait_for_bench(self, graph: Supervisor) -> None:
        """The graph ready (its drivers publish, its nodes read: graph.brought_up), until every
        controller has its robot's state and the cameras have named every robot; then the
        robots' time starts (the wall clock's now)."""
        from omni_micro_bringup.bench_start import BENCH_READY_S, wait_for_fleet_bench

        monitor, bench = self.monitor, self.bench
        assert monitor is not None and bench is not None
        wait_for_fleet_bench(monitor, graph, [robot_name(k) for k in range(self.count)],
                             lambda: bench.guard.named, BENCH_READY_S)
        misplaced = bench.guard.misplaced(self.fleet.plan.starts_m)
        if misplaced:
            raise UsageError(f'{"; ".join(misplaced)} in the robots file: the plan starts from '
                             'the file\'s places; give each robot\'s start_mm where it stands')
        bench.origin_s = time.time()

    def close(self, log_dir: Path) -> None:
        """Every robot's statuses as the coordinator took them, in its order."""
        if self.monitor is not None:
            (log_dir / 'statuses.jsonl').write_text(''.join(
                json.dumps({'robot': robot, **status}) + '\n'
                for robot, status in self.monitor.statuses))


def closest_approach(logs: list[RobotLog]) -> tuple[float, tuple[int, int] | None]:
    """The closest two robots' centres came, at the stamps both have odometry for."""
    closest, pair = math.inf, None
    for a, b in itertools.combinations(range(len(logs)), 2):
        positions = {t: (x, y) for t, x, y, _ in logs[b].route}
        for t, x, y, _ in logs[a].route:
            other = positions.get(t)
            if other is not None and math.dist((x, y), other) < closest:
                closest, pair = math.dist((x, y), other), (a, b)
    return closest, pair
