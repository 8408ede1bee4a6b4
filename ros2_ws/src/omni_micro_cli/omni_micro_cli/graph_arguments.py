"""The options of a node graph's run that several commands share: its timing (``--rtf``,
``--free-running``), ``--composed``, the live view's, the bag storage's, the simulated
camera's faults, and the bench's (``--camera``, ``--robot``, ``--image-topic``,
``--domain-id``)."""

from __future__ import annotations

import argparse
import ipaddress
import math
import os
import socket
import sys
from typing import TypedDict

from omni_micro_bringup.composition import SOURCES
from omni_micro_cli.arguments import (
    domain_id,
    non_negative_float,
    port_number,
    positive_float,
    positive_int,
    probability,
    real_time_factor,
)
from omni_micro_cli.errors import UsageError
from omni_micro_control.fleet_guard import CONTACT_GAP_M, STOP_GAP_M, UNNAMED_S
from omni_micro_tools.topics import STORAGE_NAMES


def add_timing_arguments(parser: argparse.ArgumentParser, default_rtf: str) -> None:
    """--rtf and --free-running, the same for run, demo and soak."""
    parser.add_argument('--rtf', type=real_time_factor, default=real_time_factor(default_rtf),
                        metavar='R',
                        help='real-time factor: simulated seconds per wall second, or max for '
                             f'as fast as the nodes allow (default {default_rtf}); the result '
                             'does not depend on it')
    parser.add_argument('--free-running', action='store_true',
                        help="the robot's clock does not wait for the vision and controller "
                             'nodes (what a real camera driver that does not report needs); '
                             'then a busy machine can change the run. Not with --rtf max')


def check_timing(args: argparse.Namespace) -> None:
    """Raises argparse.ArgumentTypeError for a combination that cannot work."""
    if args.free_running and math.isinf(args.rtf):
        raise argparse.ArgumentTypeError(
            '--rtf max needs the lockstep: with --free-running the nodes could not keep up '
            'with an unbounded clock; give a number')

class _ChosenLayout:
    """``--composed`` given without a count: the layout the graph chooses
    (omni_micro_bringup.node_spec.composed). Not a string, which argparse would pass through
    positive_int; true, as every option given is to the checks that refuse one."""

    def __repr__(self) -> str:
        return 'chosen'


CHOSEN_LAYOUT = _ChosenLayout()


def add_composed_argument(parser: argparse.ArgumentParser, help_text: str) -> None:
    """``--composed [CONTAINERS]``: the loop's nodes in CONTAINERS processes (as many as the
    graph chooses if not said)."""
    parser.add_argument('--composed', nargs='?', const=CHOSEN_LAYOUT, type=positive_int,
                        metavar='CONTAINERS', help=help_text)


class Composition(TypedDict):
    """GraphOptions' fields that ``--composed`` sets."""

    composed: bool
    containers: int | None


def composition_of(args: argparse.Namespace) -> Composition:
    """GraphOptions' ``composed`` and ``containers`` of ``--composed [CONTAINERS]``."""
    containers = getattr(args, 'composed', None)
    return Composition(composed=containers is not None,
                       containers=containers if isinstance(containers, int) else None)

# -- the live view (run --view, demo, soak, graph, view) ----------------------------------------
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


def add_storage_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--storage', choices=sorted(STORAGE_NAMES), default='mcap',
                        help="bag storage (default mcap, Jazzy's default)")
    parser.add_argument('--force', action='store_true',
                        help='replace an existing bag at the output path')

def add_fault_arguments(parser: argparse.ArgumentParser) -> argparse._ArgumentGroup:
    """The simulated camera's faults (vision_node's ``faults.*``), in a group of their own."""
    faults = parser.add_argument_group('fault injection (see docs/reliability.md)')
    faults.add_argument('--drop-captures', type=probability, default=0.0, metavar='P',
                        help='lose each camera capture with probability P (seeded)')
    faults.add_argument('--late-captures', type=non_negative_float, default=0.0, metavar='S',
                        help='publish each capture S simulated seconds after its exposure')
    faults.add_argument('--freeze-camera-at', type=non_negative_float, metavar='S',
                        help='from simulated time S the camera repeats its last frame')
    faults.add_argument('--fault-camera', choices=('macro', 'micro', 'both'), default='both',
                        help='which camera the faults hit (default both)')
    return faults


def fault_overrides(args: argparse.Namespace) -> dict[str, object]:
    overrides: dict[str, object] = {}
    if getattr(args, 'drop_captures', 0.0):
        overrides['faults.drop_probability'] = args.drop_captures
    if getattr(args, 'late_captures', 0.0):
        overrides['faults.delay_s'] = args.late_captures
    if getattr(args, 'freeze_camera_at', None) is not None:
        overrides['faults.frozen_after_s'] = args.freeze_camera_at
    if overrides:
        overrides['faults.camera'] = args.fault_camera
    return overrides


def image_topic(text: str) -> tuple[str, str]:
    """``CAMERA=TOPIC``: which tracker camera reads a driver's image topic."""
    camera, _, topic = text.partition('=')
    if camera not in ('macro', 'micro') or not topic.startswith('/'):
        raise argparse.ArgumentTypeError(f'expected CAMERA=TOPIC with CAMERA macro or micro and '
                                         f'an absolute topic (micro=/camera/image_raw), got '
                                         f'{text!r}')
    return camera, topic


def add_bench_arguments(parser: argparse.ArgumentParser) -> None:
    bench = parser.add_argument_group('the bench: a real camera or robot in the loop '
                                      '(docs/images.md, "The bench")')
    bench.add_argument('--camera', choices=SOURCES, default='simulated',
                       help="external: no camera_node; tracker_node reads a camera driver's "
                            'images (its params, or --image-topic) running in --domain-id')
    bench.add_argument('--robot', choices=SOURCES, default='simulated',
                       help="external: no dynamics_node; the robot's driver reads "
                            '/wheel_trajectory and publishes /joint_states (steering_joint, '
                            'wheel_1_joint .. wheel_3_joint)')
    bench.add_argument('--image-topic', type=image_topic, action='append', default=[],
                       metavar='CAMERA=TOPIC',
                       help="with --camera external: a driver's image topic for that tracker "
                            'camera, its CameraInfo on camera_info beside it (again for the '
                            'other camera); the tracker then reads only these')
    bench.add_argument('--domain-id', type=domain_id, metavar='N',
                       help='the ROS_DOMAIN_ID the drivers are in (default: ROS_DOMAIN_ID; '
                            'without external parts, a private free one)')
    bench.add_argument('--stop-gap-mm', type=stop_gap_mm, default=STOP_GAP_M * 1e3,
                       metavar='MM',
                       help='with several robots on the bench: stop every robot once two '
                            'centres would come this close within 0.2 s (default '
                            f'{STOP_GAP_M * 1e3:g}; the discs touch at 9)')
    bench.add_argument('--stop-unnamed-s', type=positive_float, default=UNNAMED_S,
                       metavar='S',
                       help='with several robots on the bench: stop every robot once one '
                            'driving a leg has turned its wheels this long unnamed by the '
                            'cameras (its joint states say when; standing, it is left to its '
                            f'controller; default {UNNAMED_S:g})')


def stop_gap_mm(text: str) -> float:
    """The guard's stop gap, no less than where two robots' discs touch."""
    value = positive_float(text)
    if value < CONTACT_GAP_M * 1e3:
        raise argparse.ArgumentTypeError(f'expected at least {CONTACT_GAP_M * 1e3:g} mm (two '
                                         f'robots\' discs touch there), got {text!r}')
    return value


# The bench's options that only several robots take (the guard's).
GUARD_OPTIONS = ('stop_gap_mm', 'stop_unnamed_s')


def bench_of(args: argparse.Namespace, default_rtf: float = 1.0) -> Bench:
    """The bench's part of a graph's options: which parts are real, the driver's image topics,
    the drivers' domain (needed with a real part: ``--domain-id`` or ROS_DOMAIN_ID). A real
    part runs at real time: ``--rtf`` left at its ``default_rtf``, or 1.

    Raises
    ------
    UsageError
        --image-topic without a real camera, --rtf other than 1 or camera faults with a real
        part, or a real part with no domain to find it in.
    """
    external = 'external' in (args.camera, args.robot)
    if args.image_topic and args.camera != 'external':
        raise UsageError('--image-topic names an external camera\'s topics: it needs --camera '
                         'external')
    if external and args.rtf not in (1.0, default_rtf):
        raise UsageError(f'with an external camera or robot the graph runs at real time: '
                         f'--rtf must be 1, got {args.rtf:g}')
    if external and fault_overrides(args):
        raise UsageError('fault injection is the simulated camera\'s: not with --camera '
                         'external or --robot external')
    domain = args.domain_id
    if external and domain is None:
        from_environment = os.environ.get('ROS_DOMAIN_ID', '')
        if not from_environment.isdigit():
            raise UsageError('with an external camera or robot, say which ROS_DOMAIN_ID its '
                             'driver is in: --domain-id N (or set ROS_DOMAIN_ID)')
        domain = int(from_environment)
    return Bench(camera=args.camera, robot=args.robot, image_topics=dict(args.image_topic),
                 domain_id=domain)


class Bench(TypedDict):
    """What :func:`bench_of` gives: GraphOptions' bench fields."""

    camera: str
    robot: str
    image_topics: dict[str, str]
    domain_id: int | None
