"""`omni-micro view`: serve a running graph's topics to Foxglove (what `run --view` starts)."""

from __future__ import annotations

import argparse
import ipaddress
import socket
import sys

from omni_micro_cli.arguments import domain_id, port_number
from omni_micro_cli.errors import UsageError

DEFAULT_HOST = '127.0.0.1'
DEFAULT_PORT = 8765


def add_view_arguments(parser: argparse.ArgumentParser, flag: bool) -> None:
    """--view-host and --view-port (and --view for the commands that start a graph)."""
    if flag:
        parser.add_argument('--view', action='store_true',
                            help='watch the run live in Foxglove: serves the graph\'s topics '
                                 f'on ws://{DEFAULT_HOST}:{DEFAULT_PORT} (Foxglove: Open '
                                 'connection > Foxglove WebSocket); changes nothing in the run')
    parser.add_argument('--view-port', type=port_number, default=DEFAULT_PORT, metavar='N',
                        help=f'port of the live view (default {DEFAULT_PORT}; 0: any free one)')
    parser.add_argument('--view-host', default=DEFAULT_HOST, metavar='ADDRESS',
                        help=f'address the live view listens on (default {DEFAULT_HOST}: '
                             'this machine only)')


def check_view_host(host: str) -> str | None:
    """The warning to give for ``host``, or None for loopback.

    Raises
    ------
    UsageError
        If ``host`` is not an IP address.
    """
    try:
        address = ipaddress.ip_address(host)
    except ValueError:
        raise UsageError(f'--view-host: expected an IP address such as 127.0.0.1, got '
                         f'{host!r}') from None
    if address.is_loopback:
        return None
    who = 'any machine that can reach this one' if address.is_unspecified else \
        f'anyone who can reach {host}'
    return (f'warning: the live view listens on {host}: {who} can connect and watch the run '
            '(they cannot drive it: no publishing, no services)')


def view_url(host: str, port: int) -> str:
    return f'ws://{host}:{port}'


def view_from_args(args: argparse.Namespace) -> tuple[str, int] | None:
    """(host, port) of the live view, having said where to connect; None without --view.

    Raises
    ------
    UsageError
        If the address is not an IP address or the port is taken: said before the graph
        starts, so that a viewer never ends a run.
    """
    if not args.view:
        return None
    warning = check_view_host(args.view_host)
    if warning:
        print(warning, file=sys.stderr)
    port = free_port(args.view_host, args.view_port)
    print(f'live view: {view_url(args.view_host, port)} (Foxglove: Open connection '
          '> Foxglove WebSocket; layout: foxglove/omni-micro.json)', file=sys.stderr)
    return args.view_host, port


def free_port(host: str, port: int) -> int:
    """``port`` if nothing listens there (0: a free one), else a UsageError naming it."""
    family = socket.AF_INET6 if ':' in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((host, port))
        except OSError as error:
            raise UsageError(f'--view-port {port}: cannot listen on {host}:{port} '
                             f'({error.strerror}); give another port, or 0 for any free one') \
                from None
        return int(probe.getsockname()[1])


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
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from rclpy.parameter import Parameter

    from omni_micro_common.node_runtime import run_node
    from omni_micro_tools.viewer_node import Viewer, stop_and_report

    warning = check_view_host(args.view_host)
    if warning:
        print(warning, file=sys.stderr)
    overrides = [Parameter('host', value=args.view_host), Parameter('port', value=args.view_port),
                 Parameter('markers', value=bool(args.markers))]
    run_node(lambda: Viewer(parameter_overrides=overrides), config_errors=(),
             on_shutdown=stop_and_report, domain_id=args.domain_id)
    return 0
