"""`omni-micro track BAG`: the tracker on recorded images, offline, before closing the loop.

For a real camera: record a few seconds of its images (the robot still, then moved by hand or
by a command), and run this with the params file you will give tracker_node. It says, frame by
frame, whether the fiducial was found or why not, when the robot counts as still, and how much
the pose scatters while it is: the spread to put in the params (``noise_px``) so that the
covariance tracker_node publishes states what the camera really does.

With ``--robots`` (several robots under the camera, each carrying its code): who the tracker
names in each frame, how often each robot is still, and every frame's robot it could not name
and why, before the bench run that needs them told apart.
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from omni_micro_cli.arguments import positive_int
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import atomic_csv, output_file

if TYPE_CHECKING:
    from omni_micro_vision.recorded_tracking import FrameRow
    from omni_micro_vision.tracked_camera import TrackedCamera


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'track',
        description="Read one camera's sensor_msgs/Image frames from a bag and run "
                    "tracker_node's image processing on each, offline: found or why not, "
                    'still or moving (the same rule as the node), and the spread of the pose '
                    'over still frames beside the covariance tracker_node would publish. The '
                    "camera's pose on the platform comes from tracker_node's params "
                    '(its package defaults, then --params). Exit 0 when at least one frame '
                    'showed the fiducial (with --robots: when every robot given was named in '
                    'a frame), 1 when none did (with --robots: when a robot never was, named), '
                    '2 for a bad argument.')
    parser.add_argument('bag', type=Path, metavar='BAG', help='a bag holding the images')
    parser.add_argument('--camera', choices=('macro', 'micro'), default='micro',
                        help='whose params (pose, field, spread) apply (default micro)')
    parser.add_argument('--image-topic', metavar='T',
                        help="the images' topic in the bag (default: the camera's image_topic "
                             'param, /camera/<camera>/image_raw)')
    parser.add_argument('--params', type=Path, metavar='FILE', action='append', default=[],
                        help='a tracker_node params file, as you will give the node; again for '
                             'another (the calibration calibrate-camera wrote, say): later '
                             'files win, as with --params-file')
    parser.add_argument('--max-frames', type=positive_int, metavar='N',
                        help='only the first N frames')
    parser.add_argument('--robots', type=robot_names, metavar='R0,R1,...',
                        help='several robots under the camera, by namespace (robot_k carries '
                             "fiducial code k, as tracker_node's robots): report per robot")
    parser.add_argument('--csv', type=output_file, metavar='FILE',
                        help='write one row per frame: stamp, found, still, x, y, heading, '
                             'reason (with --robots, one per robot seen in a frame, with its '
                             'name)')
    parser.set_defaults(handler=run)


def robot_names(text: str) -> list[str]:
    """--robots: namespaces, comma-separated, each a robot the tracker can tell."""
    from omni_micro_vision.errors import CameraConfigError
    from omni_micro_vision.fleet_tracking import robot_codes

    names = [name.strip() for name in text.split(',') if name.strip()]
    try:
        robot_codes(names)
    except CameraConfigError as error:
        raise argparse.ArgumentTypeError(str(error).removeprefix('robots: ')) from None
    if not names:
        raise argparse.ArgumentTypeError(f'{text!r}: expected robot namespaces, robot_0,...')
    return names


def _tracker_settings(args: argparse.Namespace) -> tuple[dict[str, object], str]:
    from omni_micro_bringup.params_files import check_params_file, params_from_files

    for path in args.params:
        check_params_file(path)
    values = params_from_files('tracker_node', *args.params)
    topic = args.image_topic or str(values.get(f'{args.camera}.image_topic',
                                               f'/camera/{args.camera}/image_raw'))
    return values, topic


def stamped_messages(reader: Any, connection: Any) -> Iterator[tuple[float, Any]]:
    """Each message of ``connection`` in the bag, deserialized, with its header's stamp."""
    for _, _, raw in reader.messages(connections=[connection]):
        msg = reader.deserialize(raw, connection.msgtype)
        yield msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9, msg


def run(args: argparse.Namespace) -> int:
    from omni_micro_tools.bag_reading import check_readable_bag, reading
    from omni_micro_vision.errors import CameraConfigError
    from omni_micro_vision.recorded_tracking import track_frames
    from omni_micro_vision.tracked_camera import tracked_camera

    check_readable_bag(args.bag)
    values, topic = _tracker_settings(args)
    try:
        # As tracker_node reads its parameters: the same geometry, the same poses.
        camera = tracked_camera(args.camera, values.get)
        frames_needed = int(values.get('still_frames', 3))  # type: ignore[call-overload]
        tolerance_px = float(values.get('still_tolerance_px', 0.2))  # type: ignore[arg-type]
    except (CameraConfigError, TypeError, ValueError) as error:
        raise UsageError(f'tracker params: {error}') from None
    with reading(args.bag) as reader:
        connections = [c for c in reader.connections if c.topic == topic]
        images = sorted({c.topic for c in reader.connections
                         if c.msgtype == 'sensor_msgs/msg/Image'})
        choose = f'its image topics are {images or "none"} (choose one with --image-topic)'
        if not connections:
            raise UsageError(f'{str(args.bag)!r} has no {topic}: {choose}')
        if connections[0].msgtype != 'sensor_msgs/msg/Image':
            raise UsageError(f'{topic} in {str(args.bag)!r} carries {connections[0].msgtype}, '
                             f'not sensor_msgs/msg/Image: {choose}')
        frames = itertools.islice(stamped_messages(reader, connections[0]),
                                  args.max_frames or None)
        if args.robots:
            from omni_micro_cli.commands.track_robots import track_robots

            return track_robots(args, frames, camera, frames_needed, tolerance_px)
        rows = track_frames(frames, camera, frames_needed, tolerance_px)
    return _report(args, rows, camera)


def _report(args: argparse.Namespace, rows: list[FrameRow], camera: TrackedCamera) -> int:
    from omni_micro_vision.recorded_tracking import still_spread

    total = len(rows)
    found = [row for row in rows if row[1]]
    still = [row for row in rows if row[2]]
    reasons: dict[str, int] = {}
    for row in rows:
        if not row[1]:
            reasons[row[6]] = reasons.get(row[6], 0) + 1
    print(f'{args.camera} camera, {total} frames: fiducial found in {len(found)}, still (a '
          f'capture) in {len(still)}')
    for reason, count in sorted(reasons.items(), key=lambda item: -item[1]):
        print(f'  {count:5d} x {reason}')
    spread = still_spread(rows, camera)
    if spread is None and still:
        print('spread over still frames: not measured, no two still frames come in a row')
    if spread is not None:
        x, y, heading = spread.spread_m_rad
        stated = spread.stated
        print(f'spread over still frames: x {x * 1e6:.3f} um, y {y * 1e6:.3f} '
              f'um, heading {heading * 1e3:.3f} mrad; the covariance tracker_node publishes '
              f'states x {stated.x_sigma_m * 1e6:.3f} um, y {stated.y_sigma_m * 1e6:.3f} um, '
              f'heading {stated.heading_sigma_rad * 1e3:.3f} mrad')
        print(f'to state what this camera does: {args.camera}.noise_px: {spread.noise_px:.3g}, '
              f'{args.camera}.quantisation_px: {spread.quantisation_px:g} (now '
              f'{camera.noise_px:g} and {camera.quantisation_px:g})')
    if args.csv is not None:
        atomic_csv(args.csv, ['stamp_s', 'found', 'still', 'x_m', 'y_m', 'heading_rad',
                              'reason'], rows)
        print(f'per-frame rows in {args.csv}')
    if not found:
        print('the fiducial was in no frame: check the camera params (center_m, field_m) and '
              'the images', file=sys.stderr)
        return 1
    return 0
