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
from typing import TYPE_CHECKING, Any

from omni_micro_cli.errors import UsageError
from omni_micro_cli.graph_arguments import add_view_arguments, view_from_args
from omni_micro_cli.outputs import atomic_bytes, output_file, print_json

if TYPE_CHECKING:
    from omni_micro_bringup.graph_description import TopicEndpoints
    from omni_micro_bringup.graph_options import FleetRun

# What the picture calls the orchestrator's node: the command that started the graph.
ORCHESTRATOR_LABEL = 'omni-micro (orchestration)'


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
    from omni_micro_cli.commands.fleet import planned
    from omni_micro_control.fleet_files import fleet_from

    fleet = fleet_from(robots, None, goals_per_robot=1, seed=0)
    return FleetRun(planned(fleet, seed=0), fleet.robots, fleet.controllers)


def nodes_of(topics: list[TopicEndpoints]) -> list[str]:
    return sorted({e.node for t in topics for e in (*t.publishers, *t.subscribers)})


def _label(node: str) -> str:
    from omni_micro_bringup.composition import ORCHESTRATOR_NODE

    return ORCHESTRATOR_LABEL if node == ORCHESTRATOR_NODE else node


def _qos(topic: TopicEndpoints) -> str:
    offered = topic.publishers or topic.subscribers
    kinds = sorted({f'{e.reliability}, {e.durability}' for e in offered})
    return '; '.join(kinds)


def draw(topics: list[TopicEndpoints], fmt: str) -> bytes:
    """The picture: publishers | topics (type, QoS) | subscribers, an arrow per endpoint."""
    import io

    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    # Text stays text in an SVG: searchable, and a tenth of the size of glyphs drawn as paths.
    plt.rcParams['svg.fonttype'] = 'none'

    publishers = sorted({e.node for t in topics for e in t.publishers})
    subscribers = sorted({e.node for t in topics for e in t.subscribers})
    rows = max(len(topics), len(publishers), len(subscribers), 1)
    figure, axes = plt.subplots(figsize=(15.0, 0.55 * rows + 1.2))
    axes.set_xlim(-0.1, 3.1)
    axes.set_ylim(-0.8, rows)
    axes.axis('off')

    def spread(count: int) -> list[float]:
        step = rows / max(count, 1)
        return [rows - step * (index + 0.5) for index in range(count)]

    left = dict(zip(publishers, spread(len(publishers)), strict=True))
    right = dict(zip(subscribers, spread(len(subscribers)), strict=True))
    middle = {t.topic: y for t, y in zip(topics, spread(len(topics)), strict=True)}
    colours = plt.get_cmap('tab20')
    node_box = {'boxstyle': 'round,pad=0.3', 'facecolor': '#dbe9f6', 'edgecolor': '#3b6ea5'}
    topic_box = {'boxstyle': 'square,pad=0.25', 'facecolor': '#fdf3d8', 'edgecolor': '#b58a00'}
    for index, topic in enumerate(topics):
        colour = colours(index % 20)
        y = middle[topic.topic]
        for endpoint in topic.publishers:
            axes.annotate('', xy=(0.97, y), xytext=(0.42, left[endpoint.node]),
                          arrowprops={'arrowstyle': '->', 'color': colour, 'lw': 0.9})
        for endpoint in topic.subscribers:
            axes.annotate('', xy=(2.58, right[endpoint.node]), xytext=(2.03, y),
                          arrowprops={'arrowstyle': '->', 'color': colour, 'lw': 0.9})
        axes.text(1.5, y, f'{topic.topic}\n{topic.msgtype}  [{_qos(topic)}]', ha='center',
                  va='center', fontsize=7, bbox=topic_box)
    for node, y in left.items():
        axes.text(0.2, y, _label(node), ha='center', va='center', fontsize=8, bbox=node_box)
    for node, y in right.items():
        axes.text(2.8, y, _label(node), ha='center', va='center', fontsize=8, bbox=node_box)
    axes.text(0.2, rows - 0.1 + 0.5, 'publishes', ha='center', fontsize=9, weight='bold')
    axes.text(1.5, rows - 0.1 + 0.5, 'topic, type [QoS]', ha='center', fontsize=9,
              weight='bold')
    axes.text(2.8, rows - 0.1 + 0.5, 'subscribes', ha='center', fontsize=9, weight='bold')
    axes.set_ylim(-0.8, rows + 0.9)
    buffer = io.BytesIO()
    # No date in an SVG: the same graph gives the same file.
    metadata: dict[str, Any] = {'Date': None} if fmt == 'svg' else {}
    figure.savefig(buffer, format=fmt, bbox_inches='tight', metadata=metadata)
    plt.close(figure)
    return buffer.getvalue()
