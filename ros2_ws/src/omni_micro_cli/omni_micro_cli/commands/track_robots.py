"""`omni-micro track BAG --robots ...`: who tracker_node would name in each recorded frame of
several robots under one camera, as it names them (omni_micro_vision.code_reading and
fleet_tracking), and why any robot could not be named."""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any

from omni_micro_cli.outputs import atomic_csv

if TYPE_CHECKING:
    from omni_micro_vision.recorded_tracking import RobotRow
    from omni_micro_vision.tracked_camera import TrackedCamera


def track_robots(args: argparse.Namespace, frames: Iterable[tuple[float, Any]],
                 camera: TrackedCamera, still_frames: int, tolerance_px: float) -> int:
    """Name the robots in ``frames``, print the report per robot, write the rows; exit 0 when
    every robot was named in some frame, 1 when one never was."""
    from omni_micro_vision.fleet_tracking import robot_codes
    from omni_micro_vision.recorded_tracking import name_robots

    codes = robot_codes(args.robots)
    named = name_robots(frames, camera, codes, still_frames, tolerance_px)
    return _report(args, named.frames, named.rows, named.refused, list(codes))


def _report(args: argparse.Namespace, frames: int, rows: list[RobotRow], refused: Counter[str],
            robots: list[str]) -> int:
    print(f'{args.camera} camera, {frames} frames, robots {", ".join(robots)}:')
    for robot in robots:
        named = [row for row in rows if row[1] == robot]
        print(f'  {robot}: named in {len(named)} frames, still (a capture) in '
              f'{sum(row[2] for row in named)}')
    unnamed = Counter(row[6] for row in rows if not row[1])
    for reason, count in unnamed.most_common():
        print(f'  {count:5d} x a robot not named: {reason}')
    for reason, count in refused.most_common():
        print(f'  {count:5d} x no robot: {reason}')
    if args.csv is not None:
        atomic_csv(args.csv, ['stamp_s', 'robot', 'still', 'x_m', 'y_m', 'heading_rad',
                              'reason'], rows)
        print(f'per-robot rows in {args.csv}')
    never = [robot for robot in robots if not any(row[1] == robot for row in rows)]
    if never:
        print(f'never named: {", ".join(never)} (check that each carries its code and stands '
              'whole in the field)', file=sys.stderr)
        return 1
    return 0
