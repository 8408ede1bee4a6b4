"""`omni-micro record-target --camera NAME --out BAG`: a simulated camera's frames of a
calibration target, recorded as a real camera's would be, to rehearse calibrate-camera."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_micro_cli.arguments import add_target_arguments, target_from, whole_number_in
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import output_folder


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'record-target',
        description="Record a simulated camera's frames of a calibration target lying on the "
                    "platform (camera_node's scene: chessboard or circles: the same frames, "
                    'bytes and CameraInfo), '
                    'with the mount and lens its params give (--params: any of camera_node\'s '
                    '<camera>.* settings: yaw_rad, mirrored, resolution_px, field_m, '
                    'distortion, ...). Then calibrate-camera finds the mount from the bag as it '
                    "would from a real camera's. Exit 0, or 2 for a bad argument.")
    parser.add_argument('--camera', choices=('macro', 'micro'), default='micro',
                        help='which camera (default micro)')
    parser.add_argument('--out', type=output_folder, required=True, metavar='BAG',
                        help='the bag to write')
    parser.add_argument('--params', type=Path, metavar='FILE',
                        help="a camera_node params file: the camera's mount, lens and sensor")
    parser.add_argument('--frames', type=whole_number_in(1, 1000), default=10, metavar='N',
                        help='frames to record (default 10, at camera_node\'s frame rate)')
    parser.add_argument('--force', action='store_true', help='replace an existing --out bag')
    add_target_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_bringup.params_files import check_params_file, params_from_files
    from omni_micro_common.conventions import split_stamp
    from omni_micro_sim.state import RobotState
    from omni_micro_tools.bags import check_bag_output, open_writer
    from omni_micro_tools.topics import IMAGE_TOPICS
    from omni_micro_vision.camera_frames import CameraFrames, camera_settings
    from omni_micro_vision.errors import CameraConfigError

    if args.params is not None:
        check_params_file(args.params)
    values = params_from_files('camera_node', args.params)
    try:
        target = target_from(args)
        optics, sensor = camera_settings(args.camera, values.get)
        rate_hz = float(values.get('frame_rate_hz', 30.0))  # type: ignore[arg-type]
        seed = int(values.get('seed', 0))  # type: ignore[call-overload]
    except (CameraConfigError, TypeError, ValueError) as error:
        raise UsageError(f'camera params: {error}') from None
    check_bag_output(args.out, args.force)
    index = ('macro', 'micro').index(args.camera)
    frames = CameraFrames(index, optics, sensor, seed, target)
    topics = {f'/camera/{args.camera}/{stream}': IMAGE_TOPICS[f'/camera/{args.camera}/{stream}']
              for stream in ('camera_info', 'image_raw')}
    image_topic, info_topic = (f'/camera/{args.camera}/image_raw',
                               f'/camera/{args.camera}/camera_info')
    writer, connections = open_writer(args.out, 'mcap', topics)
    try:
        for number in range(args.frames):
            sec, nanosec = split_stamp(number / rate_hz)
            info, image = frames.messages(number, sec, nanosec, RobotState(0.0, 0.0, 0.0))
            stamp = sec * 1_000_000_000 + nanosec
            writer.write(connections[info_topic], stamp, info)
            writer.write(connections[image_topic], stamp, image)
            print(f'\rframe {number + 1} of {args.frames}', end='', file=sys.stderr,
                  flush=True)
    finally:
        writer.close()
    print(f'\n{args.frames} frames of a {args.pattern[0]}x{args.pattern[1]} {args.target} target '
          f'from the {args.camera} camera in {args.out} ({image_topic}, {info_topic})',
          file=sys.stderr)
    return 0
