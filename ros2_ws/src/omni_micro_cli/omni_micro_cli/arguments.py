"""Parsers for command-line values in the user's units (mm, deg), checked at the boundary, and
the options of studies and targets that several commands share (a node graph's run options are
:mod:`omni_micro_cli.graph_arguments`')."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import Any, TypeVar

from omni_micro_cli.errors import UsageError
from omni_micro_common.conventions import MAX_SEED

T = TypeVar('T')


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


def each_once(one: Callable[[str], T], what: str) -> Callable[[str], tuple[T, ...]]:
    """A parser for comma-separated values, each read by ``one`` and given once, in the order
    given (``what`` names one of them in the refusal)."""

    def parse(text: str) -> tuple[T, ...]:
        values = tuple(one(part.strip()) for part in text.split(','))
        if len(set(values)) != len(values):
            raise argparse.ArgumentTypeError(f'expected each {what} once, got {text!r}')
        return values

    return parse


def whole_numbers_in(low: int, high: int) -> Callable[[str], tuple[int, ...]]:
    """A parser for comma-separated whole numbers in [low, high], e.g. ``10,16,42``: each
    once, in the order given."""
    return each_once(whole_number_in(low, high), 'number')


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
