"""`omni-micro fleet`: several robots on one platform (a fleet), in the fleet twin."""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from omni_micro_cli.arguments import positive_int, real_time_factor, seed_number, whole_number_in
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.graph_arguments import (
    add_bench_arguments,
    add_composed_argument,
    add_fault_arguments,
    add_view_arguments,
    bench_of,
    composition_of,
    fault_overrides,
    view_from_args,
)
from omni_micro_cli.outputs import (
    atomic_bytes,
    echo_to_stderr,
    output_file,
    output_folder,
    print_json,
)
from omni_micro_control.fleet_files import MAX_ROBOTS, ROBOT_CONTROLLERS, Fleet, fleet_from
from omni_micro_control.fleet_guard import STOP_GAP_M, UNNAMED_S
from omni_micro_control.fleet_roadmap import CLEARANCE_M

if TYPE_CHECKING:   # the graph's modules load only for a run through it
    from omni_micro_bringup.graph_options import GraphOptions
    from omni_micro_control.fleet_plan import FleetPlan


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'fleet',
        description='A fleet: several robots on one platform, as in a micro-factory; each '
                    'robot its own slip dynamics and wheel offsets, its own captures, its own '
                    'controller (the paper\'s rule, the model or the servo mode); a planner '
                    'reserves the platform (9 mm discs, centres '
                    f'planned {CLEARANCE_M * 1e3:g} mm apart, the micro field to one robot at a '
                    'time) and every robot '
                    'drives its legs once those it waits for have ended. Runs in one process '
                    '(the fleet twin), or with --graph through the node graph (one '
                    'dynamics_node for all robots, each robot\'s vision_node and '
                    'controller_node under /robot_k). Ends when every task is done, or at the '
                    'first robot lost or two robots touching (exit 1).')
    parser.add_argument('--robots', default='4', metavar='N|FILE',
                        help=f'how many robots (1..{MAX_ROBOTS}, at lattice places from the '
                             'platform\'s left edge, wheel offsets drawn from the seed), or a '
                             'YAML file of robots (start_mm, wheel_offsets_deg, controller; '
                             'docs/fleet.md)')
    add_fleet_task_arguments(parser)
    parser.add_argument('--controller', choices=ROBOT_CONTROLLERS, default='paper',
                        help="every robot's controller (a robots file may give a robot its "
                             "own): paper, section 4.1's rule (default); model, plans through "
                             'the slip model and learns the robot leg after leg; servo, rolls '
                             'corrected from captures in motion; open-loop, one move toward '
                             'each point of its legs, no feedback (docs/fleet.md)')
    parser.add_argument('--seed', type=seed_number, default=0,
                        help='seed of the drawn offsets, tasks and capture noise (default 0)')
    parser.add_argument('--graph', action='store_true',
                        help='run through the node graph, in lockstep (loopback only, a '
                             'private ROS_DOMAIN_ID; logs in out/runs/)')
    parser.add_argument('--rtf', type=real_time_factor, default=math.inf, metavar='R',
                        help='with --graph: simulated seconds per wall second, or max (the '
                             'default): as fast as the nodes allow; the run is the same')
    parser.add_argument('--vision', choices=('model', 'images'), default='model',
                        help='with --graph: model, each robot its vision_node (default); '
                             'images, one camera_node renders every robot with its code and '
                             'one tracker_node names each (the fleet\'s shared cameras; a '
                             'servo\'s captures in motion too)')
    parser.add_argument('--markers', action='store_true',
                        help='with --graph: a markers_node per robot draws it on '
                             '/robot_k/markers (RViz 2, Foxglove), in its colour, labelled')
    add_view_arguments(parser, flag=True)
    add_composed_argument(
        parser, 'with --graph: dynamics_node and every robot\'s nodes in CONTAINERS processes of '
                'omni_micro_common\'s container (if not given: one per core, or one for a '
                'single robot; with 2 or more, dynamics_node in the first and the robots shared '
                'over the others; docs/fleet.md, "The graph at scale"); the run is the same')
    parser.add_argument('--respawn', action='store_true',
                        help='with --graph: restart a robot\'s crashed vision_node or '
                             'controller_node, hold the clock meanwhile and give it its leg '
                             'again (docs/reliability.md)')
    add_fault_arguments(parser).description = (
        'with --graph: every robot\'s vision_node, each drawing from its own seed')
    parser.add_argument('--log-dir', type=output_folder, default='out/runs', metavar='DIR',
                        help='with --graph: where each node\'s log goes, in a folder per run '
                             '(default out/runs)')
    parser.add_argument('--record', type=Path, metavar='BAG',
                        help='write the run into a rosbag2 bag (mcap), each robot\'s topics '
                             'under /robot_k/: the twin its odometry and goals, --graph every '
                             'robot topic its recorder reads (docs/fleet.md); replay --robot k '
                             'plays one robot back')
    parser.add_argument('--record-images', action='store_true',
                        help='with --graph, --record and --vision images: the shared cameras\' '
                             'images and camera infos too (about 80 MB per simulated second)')
    parser.add_argument('--force', action='store_true',
                        help='replace an existing bag at --record')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object (per robot and for the whole) '
                             'alone; the table and progress go to stderr')
    parser.add_argument('--params', type=Path, action='append', default=[], metavar='FILE',
                        help='with --graph: a ROS 2 params file after the package\'s (again '
                             'for more; e.g. the bench camera\'s calibration)')
    add_bench_arguments(parser)
    parser.set_defaults(handler=run)


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


def run(args: argparse.Namespace) -> int:
    if not args.graph and args.rtf != math.inf:
        raise UsageError('--rtf paces the node graph: give it with --graph')
    for option in ('composed', 'markers', 'view', 'respawn', 'record_images'):
        if not args.graph and getattr(args, option):
            raise UsageError(f'--{option.replace("_", "-")} is a node graph\'s: give it with '
                             '--graph')
    faults = fault_overrides(args)
    if not args.graph and faults:
        raise UsageError('fault injection is a node graph\'s (vision_node\'s): give it with '
                         '--graph')
    if not args.graph and args.vision != 'model':
        raise UsageError(f'--vision {args.vision} is a node graph\'s: give it with --graph')
    bench = bench_of(args, default_rtf=math.inf)
    external = 'external' in (args.camera, args.robot)
    if not args.graph and (external or args.params):
        raise UsageError('--params and the bench (--camera, --robot external) are a node '
                         'graph\'s: give them with --graph')
    fleet = fleet_of(args)
    graph = None
    if args.graph:
        from omni_micro_bringup.graph_options import GraphOptions
        from omni_micro_bringup.params_files import check_params_file

        for path in args.params:
            check_params_file(path)
        graph = GraphOptions(seed=args.seed, real_time_factor=1.0 if external else args.rtf,
                             log_dir=args.log_dir,
                             timeout_s=WALL_TIMEOUT_S, record=args.record, force=args.force,
                             **composition_of(args), markers=args.markers,
                             view=view_from_args(args), vision=args.vision,
                             respawn=args.respawn, vision_overrides=faults,
                             record_images=args.record_images,
                             params_files=tuple(args.params), **bench,
                             echo=echo_to_stderr if external else None)
    return run_and_report(fleet, args.seed, graph, max_sim_time_s=float(args.max_sim_time),
                         record=args.record, plot=args.plot, as_json=args.json, force=args.force,
                         stop_gap_m=args.stop_gap_mm * 1e-3, unnamed_s=args.stop_unnamed_s)


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
        write_bag(record, plan, result)
    if plot is not None:
        atomic_bytes(plot, route_figure(plan, result))
        echo_to_stderr(f'routes drawn in {plot}')
    if as_json:
        print_json(summary)
    if result.outcome != DONE:
        raise RunFailed(f'{result.outcome}: {result.reason}')
    return 0


def write_bag(bag: Path, plan: Any, result: Any) -> None:
    """The bag whole, or none: a write that fails leaves nothing behind."""
    import shutil

    from omni_micro_sim.parameters import DEFAULT_PERIOD_S
    from omni_micro_tools.fleet_bag import write_fleet_bag

    try:
        count = write_fleet_bag(bag, plan, result, DEFAULT_PERIOD_S)
    except BaseException:
        shutil.rmtree(bag, ignore_errors=True)
        raise
    echo_to_stderr(f'recorded {count} messages into {bag}')
