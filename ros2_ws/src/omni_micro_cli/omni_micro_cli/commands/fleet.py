"""`omni-micro fleet`: several robots on one platform (a fleet), in the fleet twin."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from omni_micro_cli.arguments import real_time_factor, seed_number
from omni_micro_cli.errors import UsageError
from omni_micro_cli.fleet_runs import (
    WALL_TIMEOUT_S,
    add_fleet_task_arguments,
    fleet_of,
    run_and_report,
)
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
from omni_micro_cli.outputs import echo_to_stderr, output_folder
from omni_micro_control.fleet_files import MAX_ROBOTS, ROBOT_CONTROLLERS
from omni_micro_control.fleet_roadmap import CLEARANCE_M


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
