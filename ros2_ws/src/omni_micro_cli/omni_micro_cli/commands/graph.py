"""`omni-micro graph`: the node graph as a picture, read from a running graph as rqt_graph does.

The graph of the options given (the same as `run`'s: --vision images, --view, --no-markers,
--record, --robots for several robots, each under its namespace) is started with its clock
paused, every topic's publishers and subscribers are read from the ROS graph with their types
and QoS, and the graph is stopped. The picture (SVG or PNG, drawn with matplotlib, which the
lock installs: no Graphviz needed) puts who publishes on the left, the topics in the middle and
who subscribes on the right; --json prints the same as data.
"""

from __future__ import annotations

import argparse
import tempfile
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING

from omni_micro_cli.errors import UsageError
from omni_micro_cli.graph_arguments import add_view_arguments, view_from_args
from omni_micro_cli.outputs import atomic_bytes, output_file, print_json

if TYPE_CHECKING:
    from omni_micro_bringup.graph_options import FleetRun


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'graph', description=__doc__.split('\n\n', 1)[1].replace('\n', ' '))
    parser.add_argument('--out', type=output_file, metavar='FILE',
                        help='the picture: .svg or .png (default: none; --json alone prints)')
    parser.add_argument('--vision', choices=('model', 'images'), default='model',
                        help='the cameras as in `run --vision` (default model)')
    parser.add_argument('--no-markers', dest='markers', action='store_false',
                        help='without markers_node, as `run --no-markers`')
    parser.add_argument('--record', action='store_true',
                        help='with the bag recorder, as `run --record`')
    add_view_arguments(parser, flag=True)
    parser.add_argument('--robots', metavar='N|FILE',
                        help='several robots, as `run --robots` (N robots, or a YAML file of '
                             'robots): each with its nodes under /robot_k')
    parser.add_argument('--json', action='store_true',
                        help='print the topics, types, QoS, publishers and subscribers as JSON')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_bringup.graph_description import describe_graph
    from omni_micro_bringup.graph_options import GraphOptions
    from omni_micro_bringup.graph_picture import draw, nodes_of

    if args.out is None and not args.json:
        raise UsageError('give --out FILE (.svg or .png) or --json: nothing to make')
    if args.out is not None and args.out.suffix not in ('.svg', '.png'):
        raise UsageError(f'--out {str(args.out)!r}: expected a .svg or .png file')
    fleet = None if args.robots is None else fleet_run(args.robots)
    with tempfile.TemporaryDirectory(prefix='omni-micro-graph-') as scratch:
        topics = describe_graph(GraphOptions(
            goal_m=None if fleet else (0.1, 0.0), log_dir=Path(scratch) / 'logs',
            markers=args.markers, vision=args.vision, view=view_from_args(args),
            record=Path(scratch) / 'bag' if args.record else None, fleet=fleet))
    if args.out is not None:
        atomic_bytes(args.out, draw(topics, args.out.suffix[1:]))
        print(f'wrote {args.out}: {len(topics)} topics, '
              f'{len(nodes_of(topics))} nodes')
    if args.json:
        print_json([asdict(topic) for topic in topics])
    return 0


def fleet_run(robots: str) -> FleetRun:
    """Several robots' graph as ``run --robots`` brings it up: the robots given, a goal each
    drawn (the graph's shape does not depend on the goals), planned."""
    from omni_micro_bringup.graph_options import FleetRun
    from omni_micro_cli.fleet_runs import planned
    from omni_micro_control.fleet_files import fleet_from

    fleet = fleet_from(robots, None, goals_per_robot=1, seed=0)
    return FleetRun(planned(fleet, seed=0), fleet.robots, fleet.controllers)
