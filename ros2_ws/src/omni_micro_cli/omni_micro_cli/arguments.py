"""Parsers for command-line values in the user's units (mm, deg), checked at the boundary, and
the options several commands share (the live view's, the bag storage's)."""

from __future__ import annotations

import argparse
import ipaddress
import math
import socket
import sys
from collections.abc import Callable
from typing import Any, TypedDict

from omni_micro_cli.errors import UsageError
from omni_micro_common.conventions import MAX_SEED
from omni_micro_tools.topics import STORAGE_NAMES


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a number, got {text!r}') from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f'expected a finite number, got {text!r}')
    return value


def positive_float(text: str) -> float:
    value = finite_float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f'expected a number > 0, got {text!r}')
    return value


# Factors of simulated time against the wall clock (--rtf, replay --rate): beyond these a run
# would take years or its timers' periods would underflow, and no study needs them.
FACTOR_RANGE = (1e-3, 1e4)


def number_in(low: float, high: float) -> Callable[[str], float]:
    """A parser for a finite number in [low, high], refused naming the bounds."""

    def parse(text: str) -> float:
        value = finite_float(text)
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(f'expected a number in [{low:g}, {high:g}], '
                                             f'got {text!r}')
        return value

    return parse


def whole_number_in(low: int, high: int, what: str = '') -> Callable[[str], int]:
    """A parser for a whole number in [low, high] (``what`` says what the bounds are)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'expected a whole number, got {text!r}') from None
        if not low <= value <= high:
            raise argparse.ArgumentTypeError(
                f'expected a whole number in [{low}, {high}]{what}, got {text!r}')
        return value

    return parse


# ROS 2 domain ids: Fast DDS's port scheme has room for 0-232 on one machine.
domain_id = whole_number_in(0, 232, ' (a ROS domain id)')
seed_number = whole_number_in(0, MAX_SEED, ' (a seed: a ROS integer parameter)')
# A TCP port (0: any free one).
port_number = whole_number_in(0, 65535, ' (a TCP port; 0: any free one)')


def real_time_factor(text: str) -> float:
    """A real-time factor in FACTOR_RANGE, or 'max' (math.inf): as fast as the lockstep
    allows."""
    if text.strip().lower() == 'max':
        return math.inf
    low, high = FACTOR_RANGE
    try:
        return number_in(low, high)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"expected a number in [{low:g}, {high:g}] or 'max', got {text!r}") from None


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


def non_negative_float(text: str) -> float:
    value = finite_float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f'expected a number >= 0, got {text!r}')
    return value


def probability(text: str) -> float:
    value = finite_float(text)
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f'expected a probability in [0, 1], got {text!r}')
    return value


def non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a whole number, got {text!r}') from None
    if value < 0:
        raise argparse.ArgumentTypeError(f'expected a whole number >= 0, got {text!r}')
    return value


def positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected a whole number, got {text!r}') from None
    if value < 1:
        raise argparse.ArgumentTypeError(f'expected a whole number >= 1, got {text!r}')
    return value


def whole_numbers_in(low: int, high: int) -> Callable[[str], tuple[int, ...]]:
    """A parser for comma-separated whole numbers in [low, high], e.g. ``10,16,42``: each
    once, in the order given."""
    one = whole_number_in(low, high)

    def parse(text: str) -> tuple[int, ...]:
        values = tuple(one(part.strip()) for part in text.split(','))
        if len(set(values)) != len(values):
            raise argparse.ArgumentTypeError(f'expected each number once, got {text!r}')
        return values

    return parse


# --composed without a count: the layout the graph chooses (omni_micro_bringup.node_spec). Not a
# string: argparse would pass a string through positive_int, and 0 is no count a user may give.
CHOSEN_LAYOUT = 0


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
                       containers=None if containers in (None, CHOSEN_LAYOUT) else containers)


def float_list(count: int, what: str) -> Callable[[str], tuple[float, ...]]:
    """A parser for ``count`` comma-separated finite numbers, e.g. ``0,3,2``."""

    def parse(text: str) -> tuple[float, ...]:
        parts = [part.strip() for part in text.split(',')]
        if len(parts) != count:
            raise argparse.ArgumentTypeError(
                f'expected {count} comma-separated {what}, got {text!r}')
        return tuple(finite_float(part) for part in parts)

    return parse


STEERING_CHOICES = ('ideal', 'realistic')


def add_steering_argument(parser: argparse.ArgumentParser, default: str = 'ideal',
                          scope: str = '') -> None:
    """--steering, the same for every command that drives the robot."""
    parser.add_argument('--steering', choices=STEERING_CHOICES, default=default,
                        help='the steering motion: ideal (the paper: exact and instantaneous) '
                             'or realistic (motor limits, gear backlash, pivot friction; '
                             f'docs/model.md, "Steering dynamics"; default {default})' + scope)


def steering_overrides(name: str, prefix: str = 'robot.') -> dict[str, object]:
    """The ROS parameters (``<prefix>steering.*``) that give a node the steering preset
    ``name``; none for ideal, the nodes' default."""
    from omni_micro_sim.parameters import (
        STEERING_PREFIX,
        RobotParameters,
        robot_parameter_values,
        steering_preset,
    )

    if name == 'ideal':
        return {}
    values = robot_parameter_values(RobotParameters(steering=steering_preset(name)))
    return {prefix + key: value for key, value in values.items()
            if key.startswith(STEERING_PREFIX)}


def pattern(text: str) -> tuple[int, int]:
    """A calibration target's inner corners, ``COLSxROWS`` (OpenCV's convention)."""
    parts = text.lower().split('x')
    if len(parts) != 2 or not all(part.strip().isdigit() for part in parts):
        raise argparse.ArgumentTypeError(f'expected COLSxROWS inner corners (9x6), got {text!r}')
    columns, rows = (int(part) for part in parts)
    if columns < 2 or rows < 2 or columns * rows > 10_000:
        raise argparse.ArgumentTypeError(f'expected 2 to 10000 inner corners each way, got '
                                         f'{text!r}')
    return columns, rows


def add_target_arguments(parser: argparse.ArgumentParser) -> None:
    """Which calibration target lies where on the platform (record-target,
    calibrate-camera): the same words for both."""
    parser.add_argument('--target', choices=('chessboard', 'circles'), default='chessboard',
                        help='chessboard (the square at its own lowest x and y black; the '
                             'default) or circles (an asymmetric grid of dark circles, as '
                             "OpenCV's findCirclesGrid reads it)")
    parser.add_argument('--pattern', type=pattern, default=(9, 6), metavar='COLSxROWS',
                        help="as OpenCV counts it: a chessboard's inner corners, one count odd "
                             "and one even (default 9x6); a circle grid's circles per row and "
                             'rows, an odd number of rows (4x11, say)')
    parser.add_argument('--pitch-mm', type=positive_float, default=0.15, metavar='MM',
                        help="a square's side; for circles, OpenCV's square size: half the "
                             'spacing along a row, the spacing between rows (default 0.15, for '
                             'the micro camera)')
    parser.add_argument('--target-center-mm', type=float_list(2, 'millimetres'),
                        default=(100.0, 0.0), metavar='X,Y',
                        help="the target's centre on the platform (default 100,0: the micro "
                             "camera's field)")
    parser.add_argument('--target-yaw-deg', type=finite_float, default=0.0, metavar='DEG',
                        help="its rows against the platform's x axis (default 0)")


def target_from(args: argparse.Namespace) -> Any:
    """The target (:mod:`omni_micro_vision.targets`) the target arguments describe."""
    from omni_micro_vision.targets import TARGET_KINDS

    return TARGET_KINDS[args.target](args.pattern, args.pitch_mm * 1e-3,
                      (args.target_center_mm[0] * 1e-3, args.target_center_mm[1] * 1e-3),
                      math.radians(args.target_yaw_deg))


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


def add_dask_arguments(parser: argparse.ArgumentParser) -> None:
    """Where a study's runs go: a local Dask cluster (``--workers``) or a running scheduler."""
    parser.add_argument('--workers',
                        type=whole_number_in(0, 256), default=0, metavar='N',
                        help='worker processes of the local Dask cluster (default: one per '
                             'core)')
    parser.add_argument('--scheduler', metavar='tcp://HOST:PORT',
                        help='submit to this running Dask scheduler instead of a local cluster')
    parser.add_argument('--scheduler-timeout', type=positive_float, default=10.0, metavar='S',
                        help='give up connecting to --scheduler after S seconds (default 10)')


def check_dask_arguments(args: argparse.Namespace) -> None:
    """Raises UsageError for --workers beside --scheduler, or a scheduler that is no address."""
    if args.scheduler and args.workers:
        raise UsageError('--workers sizes the local cluster; a --scheduler has its own workers')
    if args.scheduler and not args.scheduler.startswith(('tcp://', 'tls://', 'inproc://')):
        raise UsageError(f'--scheduler: expected an address like tcp://HOST:8786, got '
                         f'{args.scheduler!r}')


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
