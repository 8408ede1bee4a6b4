"""What the doors to a fleet share (`fleet`, `run --robots`, and the planned fleet that `graph`
and `bench-fleet` draw or time): the task arguments, the plan with its errors said as the
command line says them, and the run in the twin or the graph, reported."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from omni_micro_cli.arguments import positive_int, whole_number_in
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.outputs import atomic_bytes, echo_to_stderr, output_file, print_json
from omni_micro_control.fleet_files import Fleet, fleet_from
from omni_micro_control.fleet_guard import STOP_GAP_M, UNNAMED_S

if TYPE_CHECKING:   # the graph's modules load only for a run through it
    from omni_micro_bringup.graph_options import GraphOptions
    from omni_micro_control.fleet_plan import FleetPlan


# The destinations add_fleet_task_arguments adds.
FLEET_TASK_OPTIONS = ('tasks', 'goals_per_robot', 'max_sim_time', 'plot')


def add_fleet_task_arguments(parser: argparse.ArgumentParser | argparse._ArgumentGroup) -> None:
    """What both doors to a fleet take (``fleet`` and ``run --robots``): its tasks,
    how long it may run, the picture of its routes."""
    parser.add_argument('--tasks', type=Path, metavar='FILE',
                        help='a YAML file of goals per robot, in order, with "after" waits '
                             '(docs/fleet.md); default: drawn from the seed, each robot to the '
                             'micro field then to a place of its own, --goals-per-robot in all')
    parser.add_argument('--goals-per-robot', type=whole_number_in(1, 20), metavar='K',
                        help='goals drawn per robot without --tasks (default 2)')
    parser.add_argument('--max-sim-time', type=positive_int, default=1800, metavar='S',
                        help='give up after this much simulated time (default 1800 s)')
    parser.add_argument('--plot', type=output_file, metavar='PNG',
                        help='draw every robot\'s route, in its colour, with its label')


def fleet_of(args: argparse.Namespace) -> Fleet:
    """The robots and tasks the arguments give."""
    if args.tasks is not None and args.goals_per_robot is not None:
        raise UsageError('--goals-per-robot is how many goals to draw: not with --tasks, whose '
                         'goals are given')
    return fleet_from(args.robots, args.tasks, args.goals_per_robot or 2, args.seed,
                      args.controller)


# How long a run through the graph may take on the wall clock (run --robots: its --timeout).
WALL_TIMEOUT_S = 3600.0


def planned(fleet: Fleet, seed: int) -> FleetPlan:
    """The plan of ``fleet``'s tasks; tasks no plan can meet refused in one line (UsageError),
    a search that gave up said with how to try again (RunFailed)."""
    from omni_micro_control.fleet_plan import PlannerGaveUpError, PlanningError, plan_fleet
    from omni_micro_control.fleet_roadmap import RoadmapError
    from omni_micro_studies.fleet_twin import check_tolerances

    try:
        check_tolerances(fleet.tasks)
        return plan_fleet(fleet.starts_m, fleet.tasks, seed=seed)
    except (PlanningError, RoadmapError) as error:
        raise UsageError(str(error)) from None
    except PlannerGaveUpError as error:     # not the tasks' fault: say how to try again
        raise RunFailed(f'{error} (seed {seed}: another --seed may plan these tasks)') from None


def run_and_report(fleet: Fleet, seed: int, graph: GraphOptions | None, *, max_sim_time_s: float,
                  record: Path | None, plot: Path | None, as_json: bool,
                  force: bool = False, stop_gap_m: float = STOP_GAP_M,
                  unnamed_s: float = UNNAMED_S) -> int:
    """Plan ``fleet``'s tasks, run them in the fleet twin or (``graph``: the graph's
    options) through the node graph, print the table (and ``as_json``, the JSON), write the
    twin's bag and the routes' plot. On the bench (real robots), ``stop_gap_m`` and
    ``unnamed_s`` are the guard's."""
    from omni_micro_studies.fleet_report import fleet_table, route_figure, summarize
    from omni_micro_studies.fleet_twin import DONE, run_fleet

    if graph is not None:
        from omni_micro_bringup.fleet_dispatch import FleetDispatch

        FleetDispatch.check_options(graph)   # refused before the planning
    started = time.perf_counter()
    plan = planned(fleet, seed)
    planned_s = time.perf_counter() - started
    if record is not None:
        from omni_micro_tools.bags import check_bag_output

        # Refused (or replaced) before anything runs, once the tasks are known to be good:
        # tasks refused leave nothing on disk.
        check_bag_output(record, force)
    legs = sum(len(robot) for robot in plan.legs)
    echo_to_stderr(f'planned {len(fleet.starts_m)} robots, {legs} legs in {planned_s:.2f} s')

    def progress(done: int, total: int, sim_time_s: float) -> None:
        echo_to_stderr(f'  {done}/{total} goals reached at {sim_time_s:.1f} s')

    if graph is not None:
        from dataclasses import replace

        from omni_micro_bringup.graph import run_graph
        from omni_micro_bringup.graph_options import FleetRun
        from omni_micro_studies.fleet_routes import told_as_the_twin

        ran = run_graph(replace(graph, fleet=FleetRun(
            plan, fleet.robots, fleet.controllers, max_sim_time_s, on_progress=progress,
            stop_gap_m=stop_gap_m, unnamed_s=unnamed_s)))
        running_wall_s = ran.wall_time_s
        echo_to_stderr(f'graph: logs in {ran.log_dir} (ROS_DOMAIN_ID {ran.domain_id}); '
                       + (f'{ran.sim_time_s:.2f} s on the wall clock from the first goal to the '
                          'last end (real robots)' if graph.external else
                          f'{ran.sim_time_s:.2f} s simulated in {running_wall_s:.1f} s of wall '
                          'time from the clock\'s start to the last goal'))
        result = told_as_the_twin(plan, ran)
    else:
        result = run_fleet(plan, robots=fleet.robots, seed=seed, controllers=fleet.controllers,
                           max_sim_time_s=max_sim_time_s, on_progress=progress)
        running_wall_s = None
    wall_s = time.perf_counter() - started
    summary = summarize(fleet, plan, result, planned_s, wall_s, running_wall_s)
    print('\n'.join(fleet_table(summary)))
    sys.stdout.flush()
    if record is not None and graph is None:   # the graph's recorder wrote its own
        write_bag(record, result)
    if plot is not None:
        atomic_bytes(plot, route_figure(plan, result))
        echo_to_stderr(f'routes drawn in {plot}')
    if as_json:
        print_json(summary)
    if result.outcome != DONE:
        raise RunFailed(f'{result.outcome}: {result.reason}')
    return 0


def write_bag(bag: Path, result: Any) -> None:
    """The bag whole, or none: a write that fails leaves nothing behind."""
    import shutil

    from omni_micro_sim.parameters import DEFAULT_PERIOD_S
    from omni_micro_tools.fleet_bag import write_fleet_bag

    try:
        count = write_fleet_bag(bag, result, DEFAULT_PERIOD_S)
    except BaseException:
        shutil.rmtree(bag, ignore_errors=True)
        raise
    echo_to_stderr(f'recorded {count} messages into {bag}')
