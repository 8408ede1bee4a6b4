"""`omni-micro run`: one goal through the ROS 2 node graph (three processes)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_micro_bringup.composition import VISION_MODES, check_camera_faults, check_record_images
from omni_micro_bringup.graph import GraphResult, run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.params_files import check_params_file
from omni_micro_bringup.platform_bounds import check_goal
from omni_micro_cli.arguments import (
    add_steering_argument,
    float_list,
    positive_float,
    seed_number,
    steering_overrides,
)
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.fleet_runs import FLEET_TASK_OPTIONS, add_fleet_task_arguments
from omni_micro_cli.graph_arguments import (
    GUARD_OPTIONS,
    add_bench_arguments,
    add_composed_argument,
    add_fault_arguments,
    add_storage_arguments,
    add_timing_arguments,
    add_view_arguments,
    bench_of,
    check_timing,
    composition_of,
    fault_overrides,
    view_from_args,
)
from omni_micro_cli.outputs import echo_to_stderr, output_folder, print_json
from omni_micro_common.conventions import GOAL_TOLERANCE_M
from omni_micro_control.fleet_files import OPEN_LOOP, ROBOT_CONTROLLERS, controller_settings


def add_graph_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--params', type=Path, metavar='FILE', action='append', default=[],
                        help='a ROS params YAML applied to every node after its package '
                             'defaults (sections dynamics_node:, vision_node:, controller_node:); '
                             'again for another (a calibration beside your own file): later '
                             'files win, as with --params-file')
    add_timing_arguments(parser, default_rtf='1')
    add_steering_argument(parser)
    parser.add_argument('--seed', type=seed_number, default=0, metavar='N',
                        help='camera noise seed (default 0); the same seed gives the same run '
                             'at any --rtf and any load')
    parser.add_argument('--timeout', type=positive_float, default=600.0, metavar='S',
                        help='give up after this many wall seconds (default 600)')
    parser.add_argument('--log-dir', type=output_folder, default='out/runs', metavar='DIR',
                        help='node logs go to a new folder under DIR (default out/runs)')
    parser.add_argument('--quiet', action='store_true',
                        help="do not echo the nodes' logs (they are still kept)")
    parser.add_argument('--record', type=output_folder, metavar='BAG',
                        help='record every topic into this rosbag2 bag (a recorder node in its '
                             'own process; simulated-time stamps)')
    parser.add_argument('--vision', choices=sorted(VISION_MODES), default='model',
                        help='model: vision_node measures the pose with the cameras\' noise '
                             'model (default); images: camera_node renders each camera\'s '
                             'images and tracker_node finds the robot in them, as a real '
                             'camera and its tracker would (docs/images.md)')
    parser.add_argument('--record-images', action='store_true',
                        help='with --record and --vision images (or --camera external: the '
                             "driver's): the images and camera infos too (about 80 MB per "
                             'simulated second at the default sizes)')
    parser.add_argument('--captures-in-motion', action='store_true',
                        help='vision_node (or tracker_node, on images) also publishes captures '
                             'of the moving robot on /camera/<name>/pose_in_motion, stamped at '
                             'mid-exposure (a '
                             "recording keeps them; each camera's rate, exposure and latency: "
                             '<name>.motion.* in --params; docs/images.md, "Captures in '
                             'motion")')
    parser.add_argument('--no-markers', dest='markers', action='store_false',
                        help='do not start markers_node (the /markers it draws for RViz 2 and '
                             'Foxglove; the run is the same with or without it)')
    add_composed_argument(
        parser, "run the loop's nodes (dynamics, the cameras' stand-in, the controller) in "
                'CONTAINERS processes of one executor each (if not given: one for a single '
                'robot, one per core for several; with 2 or more, dynamics and the cameras in '
                'the first, the robots shared over the others): faster at --rtf max, the same '
                'run and bag (docs/graph.md, "The loop in one process"); separate processes '
                'stay the default, so that a real camera or robot can replace one')
    add_storage_arguments(parser)
    add_view_arguments(parser, flag=True)


def open_loop_seconds(text: str) -> float:
    """An open-loop move's duration: > 0 and at most the controller's limit."""
    from omni_micro_control.feedback_config import MAX_OPEN_LOOP_S

    value = positive_float(text)
    if value > MAX_OPEN_LOOP_S:
        raise argparse.ArgumentTypeError(f'expected at most {MAX_OPEN_LOOP_S:g} s (a minute at '
                                         f'cruise speed runs off any platform), got {text!r}')
    return value


def add_controller_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--controller', choices=ROBOT_CONTROLLERS, default='paper',
                        help="paper: section 4.1's rule (default); model: plan each move "
                             "through the slip model and identify the robot's offsets as it "
                             'goes; servo: keep the robot rolling, corrected from captures in '
                             'motion, and stop once at the end; open-loop: one move toward '
                             'each goal for the time the nominal robot takes, no feedback '
                             '(docs/control.md)')
    parser.add_argument('--tolerance-um', type=positive_float, metavar='UM',
                        help="reached when a capture's distance to the goal plus its 95 %% "
                             f'uncertainty is within this (default {GOAL_TOLERANCE_M * 1e6:g}, '
                             'from the params)')


def controller_overrides(args: argparse.Namespace) -> dict[str, object]:
    overrides: dict[str, object] = {}
    if getattr(args, 'controller', 'paper') != 'paper':
        overrides.update(controller_settings(args.controller))
    if getattr(args, 'tolerance_um', None) is not None:
        overrides['tolerance_m'] = args.tolerance_um * 1e-6
    return overrides


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'run',
        description='Start dynamics_node, vision_node and controller_node as three processes '
                    '(with --vision images, camera_node and tracker_node in place of '
                    'vision_node; loopback only, private ROS_DOMAIN_ID), drive the robot from '
                    'the origin '
                    'to the goal with vision feedback (or one open-loop move), print where it '
                    'really stopped, and shut the graph down. Exit 0 when the goal was reached '
                    '(or the open-loop move completed), 1 otherwise (a node died, the '
                    'controller gave up or was lost, or the camera that sees the goal cannot '
                    'resolve the tolerance: unresolved), 2 for a bad argument or parameter '
                    '(nothing is started).')
    parser.add_argument('--goal-mm', type=float_list(2, 'numbers X,Y in mm'),
                        metavar='X,Y', help='goal in the platform frame, mm, e.g. 100,0 (needed '
                                            'unless --robots)')
    parser.add_argument('--open-loop', type=open_loop_seconds, metavar='S',
                        help='no feedback: one move of S seconds toward the goal (the paper '
                             'uses 7 s for 100 mm)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone, the outcome and true '
                             'final pose (the rest on stderr)')
    add_controller_arguments(parser)
    add_graph_arguments(parser)
    add_bench_arguments(parser)
    faults = add_fault_arguments(parser)
    faults.add_argument('--respawn', action='store_true',
                        help='restart a crashed vision_node or controller_node and go on')
    fleet = parser.add_argument_group('several robots on one platform (docs/fleet.md)')
    fleet.add_argument('--robots', metavar='N|FILE',
                       help='a fleet: N robots (or a YAML file of robots), each with '
                            'its vision_node and controller_node under /robot_k, one '
                            'dynamics_node for all; with --tasks (or drawn goals), --controller '
                            '(every robot\'s; a robots file may give one its own), --seed, --rtf, '
                            '--timeout, --log-dir, --json and those below; what omni-micro '
                            'fleet --graph runs')
    add_fleet_task_arguments(fleet)
    parser.set_defaults(handler=run)
    _DEFAULTS.update({action.dest: action.default for action in parser._actions})


# What run's options are when not given: with --robots, one given that only a single robot's run
# reads is refused, named.
_DEFAULTS: dict[str, object] = {}
# What a run of several robots reads (the rest is the single robot's).
FLEET_OPTIONS = ('robots', 'tasks', 'controller', 'seed', 'rtf', 'timeout', 'log_dir', 'record',
                 'composed', 'markers', 'view', 'view_port', 'view_host', 'json', 'quiet', 'help',
                 'vision', 'force', 'respawn', 'record_images', 'drop_captures', 'late_captures',
                 'freeze_camera_at', 'fault_camera', 'camera', 'robot', 'image_topic',
                 'domain_id', 'params', *GUARD_OPTIONS, *FLEET_TASK_OPTIONS)


def fleet_run(args: argparse.Namespace) -> int:
    """``run --robots``: the fleet through the graph, as ``fleet --graph`` runs it."""
    from omni_micro_cli.fleet_runs import fleet_of, run_and_report

    others = sorted(f'--{dest.replace("_", "-")}' for dest, default in _DEFAULTS.items()
                    if dest not in FLEET_OPTIONS and getattr(args, dest, default) != default)
    if others:
        raise UsageError(f'{", ".join(others)}: a single robot\'s run only; with --robots '
                         'give --tasks, --controller, --vision, --seed, --rtf, --timeout, '
                         '--log-dir, --record, --record-images, --force, --composed, '
                         '--no-markers, --view, --respawn, the camera faults, --json, '
                         '--quiet, --goals-per-robot, --max-sim-time, --plot, --params and '
                         'the bench\'s options')
    fleet = fleet_of(args)
    bench = bench_of(args)
    external = 'external' in (args.camera, args.robot)
    for path in args.params:
        check_params_file(path)
    graph = GraphOptions(seed=args.seed, real_time_factor=args.rtf, log_dir=args.log_dir,
                         timeout_s=args.timeout, record=args.record, force=args.force,
                         **composition_of(args), respawn=args.respawn,
                         vision_overrides=fault_overrides(args),
                         record_images=args.record_images,
                         # Real robots have no odometry to draw.
                         markers=args.markers and not external,
                         view=view_from_args(args), vision=args.vision,
                         params_files=tuple(args.params), **bench,
                         echo=echo_to_stderr if external and not args.quiet else None)
    return run_and_report(fleet, args.seed, graph, max_sim_time_s=float(args.max_sim_time),
                         record=args.record, plot=args.plot, as_json=args.json,
                         force=args.force, stop_gap_m=args.stop_gap_mm * 1e-3,
                         unnamed_s=args.stop_unnamed_s)


def options_from_args(args: argparse.Namespace, goal_m: tuple[float, float],
                      open_loop_s: float | None) -> GraphOptions:
    params_files = tuple(args.params)
    for path in params_files:
        check_params_file(path)
    check_goal(goal_m, params_files)
    try:
        check_timing(args)
    except argparse.ArgumentTypeError as error:
        raise UsageError(str(error)) from None
    faults = fault_overrides(args)
    check_camera_faults(faults, args.vision)
    bench = bench_of(args)
    check_record_images(args.record_images, args.record, args.vision, args.camera)
    return GraphOptions(goal_m=goal_m, seed=args.seed, real_time_factor=args.rtf,
                        lockstep=not args.free_running,
                        open_loop_s=open_loop_s, params_files=params_files,
                        timeout_s=args.timeout, log_dir=args.log_dir,
                        echo=None if args.quiet else echo_to_stderr, record=args.record,
                        storage=args.storage, force=args.force,
                        vision_overrides=faults, vision=args.vision,
                        record_images=args.record_images,
                        captures_in_motion=getattr(args, 'captures_in_motion', False),
                        controller_overrides={**controller_overrides(args),
                                              **preset_under_params(args, 'controller_node',
                                                                    'model.robot.')},
                        dynamics_overrides=preset_under_params(args, 'dynamics_node', 'robot.'),
                        respawn=getattr(args, 'respawn', False),
                        # markers_node draws the robot from its odometry, which a real robot
                        # has not.
                        markers=args.markers and args.robot != 'external',
                        view=view_from_args(args), **composition_of(args), **bench)


def preset_under_params(args: argparse.Namespace, node: str,
                        prefix: str) -> dict[str, object]:
    """The --steering preset's values for ``node`` (the robot, ``robot.``; the model
    controller's model of it, ``model.robot.``: it knows the preset's form, not this robot),
    except those the user's --params file sets: the file says what this robot has (e.g. its
    measured backlash), the preset the rest."""
    overrides = steering_overrides(args.steering, prefix)
    if args.params and overrides:
        from omni_micro_common import params

        given = params.node_parameters(list(args.params), node)
        overrides = {name: value for name, value in overrides.items() if name not in given}
    return overrides


def summary_line(result: GraphResult, external: bool = False) -> str:
    where = ('last seen by the camera at' if external else 'stopped at')
    took = (f'{result.wall_time_s:.2f} s on the wall clock' if external else
            f'{result.sim_time_s:.2f} s simulated in {result.wall_time_s:.2f} s wall')
    return (f'{result.outcome}: {where} ({result.final_x_m * 1e3:.4f}, '
            f'{result.final_y_m * 1e3:.4f}) mm, {result.deviation_m * 1e3:.4f} mm from the goal, '
            f'{result.periods} periods, {took}; logs in {result.log_dir}')


def run(args: argparse.Namespace) -> int:
    if args.robots is not None:
        return fleet_run(args)
    several = [f'--{dest.replace("_", "-")}' for dest in (*FLEET_TASK_OPTIONS, *GUARD_OPTIONS)
               if getattr(args, dest) != _DEFAULTS[dest]]
    if several:
        raise UsageError(f'{", ".join(several)}: for several robots; give --robots N|FILE')
    if args.goal_mm is None:
        raise UsageError('--goal-mm X,Y is needed (or --robots N|FILE for several robots)')
    goal = (args.goal_mm[0] * 1e-3, args.goal_mm[1] * 1e-3)
    options = options_from_args(args, goal, args.open_loop)
    result = run_graph(options)
    print(summary_line(result, options.external), file=sys.stderr)
    if args.json:
        print_json(result.as_json())
    succeeded = 'completed' if args.open_loop or args.controller == OPEN_LOOP else 'reached'
    if result.outcome != succeeded:
        raise RunFailed(f'controller_node reported {result.outcome}: {result.reason}')
    return 0
