"""`omni-micro demo`: the paper's results reproduced, the closed loop through the ROS 2 graph.

The open-loop figures (Figs. 6, 7, 8, 11) come from the slip core; Fig. 11's comparison of open
loop (7 s) and vision feedback runs through the three node processes, as a user would run it,
and once more with rendered images and the tracker in place of the camera model.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_cli.arguments import add_steering_argument, seed_number, steering_overrides
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.graph_arguments import (
    add_storage_arguments,
    add_timing_arguments,
    add_view_arguments,
    check_timing,
    view_from_args,
)
from omni_micro_cli.outputs import echo_to_stderr, output_folder, staged_directory
from omni_micro_sim import paper

if TYPE_CHECKING:
    from omni_micro_bringup.graph import GraphResult


OPEN_LOOP_S = paper.FIG11_OPEN_LOOP.duration_s
RUNS = ('open_loop', 'closed_loop', 'model', 'images', 'realistic_steering', 'servo')
# The servo's run aims at the tolerance the issue that asked for it set (docs/control.md).
SERVO_TOLERANCE_M = 0.5e-6


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'demo',
        description="Run the paper's Fig. 11 scenario, (0,0) -> (100,0) mm, through the ROS 2 "
                    "node graph: one open-loop move of 7 s, then vision feedback by the "
                    "paper's rule, then by the model-based controller, then by the paper's "
                    "rule on rendered camera images (camera_node + tracker_node), then by the "
                    "paper's rule on a robot with realistic steering, then by the servo mode "
                    "(within 0.5 um, corrected while rolling); print the deviations beside the "
                    "paper's (13 mm and 0.0124 mm) and write the comparison figure, plus the "
                    "open-loop figures of Figs. 6-8 from the core. "
                    "Exit 0 when every closed loop reached the goal, 1 otherwise, 2 for a bad "
                    "argument.")
    parser.add_argument('--out', type=output_folder, default='out/demo', metavar='DIR',
                        help='where the figures and summary go (default out/demo)')
    add_timing_arguments(parser, default_rtf='max')
    add_steering_argument(parser, scope=". Here: the model-based and image runs' steering; "
                          "the paper's rows stay ideal (their numbers are the point), and the "
                          "last row is always the paper's rule with realistic steering")
    parser.add_argument('--seed', type=seed_number, default=0, metavar='N',
                        help='camera noise seed (default 0)')
    parser.add_argument('--verbose', action='store_true', help="echo the nodes' logs")
    parser.add_argument('--record', type=output_folder, metavar='DIR',
                        help='record the runs as bags DIR/fig11_open_loop, '
                             'DIR/fig11_closed_loop, DIR/fig11_model, DIR/fig11_images and '
                             'DIR/fig11_realistic_steering '
                             '(without the images themselves)')
    add_storage_arguments(parser)
    add_view_arguments(parser, flag=True)
    parser.set_defaults(handler=run)


def _progress(message: str) -> None:
    print(f'demo: {message}', file=sys.stderr, flush=True)


def bag_paths(args: argparse.Namespace) -> dict[str, Path | None]:
    from omni_micro_tools.bags import check_bag_output

    if args.record is None:
        return dict.fromkeys(RUNS)
    args.record.mkdir(parents=True, exist_ok=True)
    paths = {name: args.record / f'fig11_{name}' for name in RUNS}
    for path in paths.values():
        check_bag_output(path, args.force)   # refuse before anything runs
    return paths


def graph_run(args: argparse.Namespace, open_loop_s: float | None, log_root: Path,
              bag: Path | None, mode: str = 'paper', vision: str = 'model',
              steering: str = 'ideal', tolerance_m: float | None = None) -> GraphResult:
    from omni_micro_bringup.graph import run_graph

    return run_graph(GraphOptions(
        goal_m=paper.FIG11_GOAL_M, seed=args.seed, real_time_factor=args.rtf,
        lockstep=not args.free_running,
        open_loop_s=open_loop_s, log_dir=log_root, follow_route=True,
        echo=echo_to_stderr if args.verbose else None, record=bag, storage=args.storage,
        force=args.force, view=view_from_args(args), vision=vision,
        controller_overrides={**({'mode': mode, **steering_overrides(steering, 'model.robot.')}
                                 if mode != 'paper' else {}),
                              **({'tolerance_m': tolerance_m} if tolerance_m else {})},
        dynamics_overrides=steering_overrides(steering)))


def comparison_table(open_loop: GraphResult, closed_loop: GraphResult,
                     model: GraphResult, images: GraphResult,
                     realistic: GraphResult, servo: GraphResult) -> str:

    return '\n'.join([
        '| Fig. 11, (0,0) -> (100,0) mm | paper | this graph |',
        '|---|---|---|',
        f'| open loop, 7 s: deviation | {paper.FIG11_PUBLISHED_OPEN_LOOP_DEVIATION_MM} mm | '
        f'{open_loop.deviation_m * 1e3:.3f} mm |',
        f'| vision feedback: deviation | {paper.FIG11_PUBLISHED_CLOSED_LOOP_DEVIATION_MM} mm | '
        f'{closed_loop.deviation_m * 1e3:.4f} mm ({closed_loop.deviation_m * 1e6:.2f} um) |',
        f'| vision feedback: periods | - | {closed_loop.periods} |',
        f'| vision feedback: simulated time | - | {closed_loop.sim_time_s:.2f} s |',
        f'| model-based controller: deviation | - | {model.deviation_m * 1e6:.2f} um |',
        f'| model-based controller: periods | - | {model.periods} |',
        f'| model-based controller: simulated time | - | {model.sim_time_s:.2f} s |',
        f'| vision feedback on rendered images: deviation | - | '
        f'{images.deviation_m * 1e6:.2f} um |',
        f'| vision feedback on rendered images: periods | - | {images.periods} |',
        f'| vision feedback on rendered images: simulated time | - | '
        f'{images.sim_time_s:.2f} s |',
        f'| vision feedback, realistic steering: deviation | - | '
        f'{realistic.deviation_m * 1e6:.2f} um |',
        f'| vision feedback, realistic steering: periods | - | {realistic.periods} |',
        f'| vision feedback, realistic steering: simulated time | - | '
        f'{realistic.sim_time_s:.2f} s |',
        f'| servo mode, 0.5 um tolerance: deviation | - | {servo.deviation_m * 1e6:.2f} um |',
        f'| servo mode: moves and stops | - | {servo.periods} and '
        f'{servo.status.get("stops", "?")} |',
        f'| servo mode: simulated time | - | {servo.sim_time_s:.2f} s |',
        ''])


def run(args: argparse.Namespace) -> int:
    from omni_micro_studies import open_loop_figures
    from omni_micro_studies import paper_figures as plots

    try:
        check_timing(args)
    except argparse.ArgumentTypeError as error:
        raise UsageError(str(error)) from None
    started = time.perf_counter()
    bags = bag_paths(args)
    # The graph runs log straight into --out: a run that fails names its logs, and they stay
    # (the figures and tables appear only if every run succeeds).
    logs = args.out / 'logs'
    with staged_directory(args.out) as scratch:
        _progress('open-loop figures from the slip core (Figs. 6, 7, 8, 11)')
        open_loop_figures.write_figures(scratch, angle_step_deg=2.0, offset_step_deg=0.25,
                                        progress=lambda line: echo_to_stderr(f'[figures] {line}'))
        _progress(f'Fig. 11 open loop through the node graph ({OPEN_LOOP_S:g} s move, '
                  f'rtf {args.rtf:g})')
        open_loop = graph_run(args, OPEN_LOOP_S, logs, bags['open_loop'])
        _progress(f'  deviation {open_loop.deviation_m * 1e3:.3f} mm')
        _progress('Fig. 11 with vision feedback through the node graph')
        closed_loop = graph_run(args, None, logs, bags['closed_loop'])
        _progress(f'  {closed_loop.outcome}: deviation {closed_loop.deviation_m * 1e6:.2f} um '
                  f'after {closed_loop.periods} periods')
        _progress('Fig. 11 with the model-based controller through the node graph')
        model = graph_run(args, None, logs, bags['model'], mode='model',
                          steering=args.steering)
        _progress(f'  {model.outcome}: deviation {model.deviation_m * 1e6:.2f} um '
                  f'after {model.periods} periods')
        _progress('Fig. 11 with vision feedback on rendered images (camera_node + '
                  'tracker_node)')
        images = graph_run(args, None, logs, bags['images'], vision='images',
                           steering=args.steering)
        _progress(f'  {images.outcome}: deviation {images.deviation_m * 1e6:.2f} um '
                  f'after {images.periods} periods')
        _progress('Fig. 11 with vision feedback on a robot with realistic steering')
        realistic = graph_run(args, None, logs, bags['realistic_steering'],
                              steering='realistic')
        _progress(f'  {realistic.outcome}: deviation {realistic.deviation_m * 1e6:.2f} um '
                  f'after {realistic.periods} periods')
        _progress('Fig. 11 by the servo mode through the node graph')
        servo = graph_run(args, None, logs, bags['servo'], mode='servo',
                          tolerance_m=SERVO_TOLERANCE_M)
        _progress(f'  {servo.outcome}: deviation {servo.deviation_m * 1e6:.2f} um in '
                  f'{servo.sim_time_s:.2f} s, {servo.periods} move(s)')
        for name, outcome, reason in (
                ('closed loop', closed_loop.outcome, closed_loop.reason),
                ('model-based loop', model.outcome, model.reason),
                ('loop on images', images.outcome, images.reason),
                ('loop with realistic steering', realistic.outcome, realistic.reason),
                ('servo loop', servo.outcome, servo.reason)):
            if outcome != 'reached':
                raise RunFailed(f'the {name} ended {outcome}: {reason}')
        used = np.array([c[1:3] for c in closed_loop.captures]).reshape(-1, 2)
        plots.closed_loop_comparison(
            scratch / 'fig11_graph_comparison.png',
            np.array([r[1:] for r in open_loop.route]).reshape(-1, 2),
            np.array([r[1:] for r in closed_loop.route]).reshape(-1, 2), used,
            paper.FIG11_GOAL_M, zoom_half_width_m=20e-6,
            title='Fig. 11 through the node graph')
        table = comparison_table(open_loop, closed_loop, model, images, realistic, servo)
        (scratch / 'fig11_graph.md').write_text(table)
        summaries = {'open_loop': open_loop.as_json(), 'closed_loop': closed_loop.as_json(),
                     'model': model.as_json(), 'images': images.as_json(),
                     'realistic_steering': realistic.as_json(), 'servo': servo.as_json()}
        (scratch / 'fig11_graph.json').write_text(json.dumps(summaries, indent=2))
        core_table = (scratch / 'comparison.md').read_text()
    print(core_table)
    print(table)
    if args.record is not None:
        print(f'bags in {args.record}/ (omni-micro analyze {bags["closed_loop"]} --out DIR)')
    print(f'figures in {args.out}/ ({time.perf_counter() - started:.1f} s)')
    return 0
