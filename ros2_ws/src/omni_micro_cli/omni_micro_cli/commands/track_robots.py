"""`omni-micro track BAG --robots ...`: who tracker_node would name in each recorded frame of
several robots under one camera, as it names them (omni_micro_vision.code_reading and
fleet_tracking), and why any robot could not be named."""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from typing import TYPE_CHECKING, Any

from omni_micro_cli.outputs import atomic_csv
from omni_micro_common.topic_names import robot_name

if TYPE_CHECKING:
    from omni_micro_vision.tracked_camera import TrackedCamera

# One row per robot seen in a frame: stamp, robot ('' when not named), still, x, y, heading,
# reason.
Row = tuple[float, str, bool, float, float, float, str]


def track_robots(args: argparse.Namespace, reader: Any, connection: Any,
                 camera: TrackedCamera, still_frames: int, tolerance_px: float) -> int:
    """Read the frames, print the report per robot, write the rows; exit 0 when every robot
    was named in some frame, 1 when one never was."""
    from omni_micro_vision.code_reading import identify
    from omni_micro_vision.encodings import full_scale
    from omni_micro_vision.errors import CameraConfigError
    from omni_micro_vision.fleet_tracking import robot_codes
    from omni_micro_vision.image_messages import image_array
    from omni_micro_vision.tracking import StillnessRule

    codes = robot_codes(args.robots)
    names = {code: name for name, code in codes.items()}
    tolerance_m = tolerance_px * min(camera.plane.pixel_size_m)
    stillness = {code: StillnessRule(still_frames, tolerance_m) for code in names}
    rows: list[Row] = []
    frames, scale = 0, 0
    refused: Counter[str] = Counter()
    for _, _, raw in reader.messages(connections=[connection]):
        msg = reader.deserialize(raw, connection.msgtype)
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        frames += 1
        try:
            pixels = image_array(msg, camera.plane.resolution_px)
            scale = max(scale, full_scale(pixels, camera.bit_depth))
            sightings, reason = identify(pixels, camera.plane, scale)
        except CameraConfigError as error:
            sightings, reason = [], f'refused: {error}'
        if not sightings:
            refused[reason] += 1
        seen = set()
        for sighting in sightings:
            x, y, heading = sighting.pose
            if sighting.robot in names:
                seen.add(sighting.robot)
                still = stillness[sighting.robot].still(x, y)
                rows.append((stamp, names[sighting.robot], still, x, y, heading, ''))
            else:
                why = sighting.reason or (f'{robot_name(sighting.robot)} is not one of --robots'
                                          if sighting.robot is not None else 'not named')
                rows.append((stamp, '', False, x, y, heading, why))
        for code in set(names) - seen:
            stillness[code].reset()
        if args.max_frames and frames >= args.max_frames:
            break
    return _report(args, frames, rows, refused, list(codes))


def _report(args: argparse.Namespace, frames: int, rows: list[Row], refused: Counter[str],
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
