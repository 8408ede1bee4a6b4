"""`omni-micro view`: serve a running graph's topics to Foxglove (what `run --view` starts)."""

from __future__ import annotations

import argparse
import sys

from omni_micro_cli.arguments import domain_id
from omni_micro_cli.graph_arguments import add_view_arguments, check_view_host


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'view',
        description='Subscribe to a running graph\'s topics (ROS_DOMAIN_ID or --domain-id) and '
                    'serve them over the Foxglove WebSocket protocol, CDR-encoded with ros2msg '
                    'schemas. Only listens; clients cannot publish. Ctrl-C stops it.')
    add_view_arguments(parser, flag=False)
    parser.add_argument('--domain-id', type=domain_id, metavar='N',
                        help='ROS domain of the graph (default: ROS_DOMAIN_ID)')
    parser.add_argument('--no-markers', dest='markers', action='store_false',
                        help='do not serve /markers (a graph without markers_node)')
    parser.add_argument('--robots', type=robot_namespaces, metavar='N|R0,R1,...',
                        help="a fleet's graph: serve each robot's topics under its "
                             'namespace, robot_0 to robot_{N-1} or those named')
    parser.set_defaults(handler=run)


def robot_namespaces(text: str) -> list[str]:
    """--robots: a count of robots (robot_0, ...) or their namespaces, comma-separated."""
    from omni_micro_common.topic_names import is_plain_name, robot_name

    if text.isdigit() and int(text) >= 1:
        return [robot_name(k) for k in range(int(text))]
    names = [name.strip() for name in text.split(',') if name.strip()]
    strangers = [name for name in names if not is_plain_name(name)]
    if not names or strangers:
        raise argparse.ArgumentTypeError(
            f'{text!r}: expected a number of robots or namespaces such as robot_0,robot_1')
    return names


def run(args: argparse.Namespace) -> int:
    from rclpy.parameter import Parameter

    from omni_micro_common.node_runtime import run_node
    from omni_micro_tools.viewer_node import Viewer, stop_and_report

    warning = check_view_host(args.view_host)
    if warning:
        print(warning, file=sys.stderr)
    overrides = [Parameter('host', value=args.view_host), Parameter('port', value=args.view_port),
                 Parameter('markers', value=bool(args.markers)),
                 *([Parameter('robots', value=args.robots)] if args.robots else [])]
    run_node(lambda: Viewer(parameter_overrides=overrides), config_errors=(),
             on_shutdown=stop_and_report, domain_id=args.domain_id)
    return 0
