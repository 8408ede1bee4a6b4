"""`omni-micro calibrate-camera BAG`: a camera's map to the platform from recorded frames of a
calibration target lying on it, as a params file for tracker_node."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any

from omni_micro_cli.arguments import add_target_arguments, target_from, whole_number_in
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import atomic_text, output_file


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'calibrate-camera',
        description="Find where a camera's pixels lie on the platform from its recorded frames "
                    'of a chessboard or a circle grid lying there (where you say: '
                    '--target-center-mm, --target-yaw-deg): OpenCV finds its points, takes the '
                    "lens out with the CameraInfo's K and D (from camera_calibration; all zero: "
                    'none), and fits '
                    'one homography. Prints the RMS residual in pixels and micrometres and '
                    'writes a params file for tracker_node holding the calibration (give it '
                    'beside your own: --params-file yours.yaml --params-file OUT). A target '
                    'cannot show a mirrored image: say --mirrored if the camera mirrors (a '
                    "mirror in the optics, a driver's flip). Exit 0; 1 when the target is not "
                    'found, is ambiguous or fits poorly; 2 for a bad argument.')
    parser.add_argument('bag', type=Path, metavar='BAG', help='a bag with the frames')
    parser.add_argument('--camera', choices=('macro', 'micro'), default='micro',
                        help='the tracker camera the calibration is for (default micro)')
    parser.add_argument('--image-topic', metavar='T',
                        help='the frames (default /camera/<camera>/image_raw)')
    parser.add_argument('--info-topic', metavar='T',
                        help='their CameraInfo (default: camera_info beside the image topic)')
    parser.add_argument('--mirrored', action='store_true',
                        help='the camera mirrors the image')
    parser.add_argument('--max-frames', type=whole_number_in(1, 1000), default=30, metavar='N',
                        help='frames averaged (default 30)')
    parser.add_argument('--out', type=output_file, required=True, metavar='FILE.yaml',
                        help='the params file to write')
    add_target_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_tools.bag_reading import check_readable_bag, reading
    from omni_micro_vision.calibration import CalibrationError, calibrate
    from omni_micro_vision.errors import CameraConfigError
    from omni_micro_vision.geometry import Lens
    from omni_micro_vision.image_messages import image_array

    check_readable_bag(args.bag)
    image_topic = args.image_topic or f'/camera/{args.camera}/image_raw'
    info_topic = args.info_topic or image_topic.rsplit('/', 1)[0] + '/camera_info'
    try:
        target = target_from(args)
    except CameraConfigError as error:
        raise UsageError(str(error)) from None
    frames = []
    lens: Lens | None = None
    size: tuple[int, int] | None = None
    with reading(args.bag) as reader:
        by_topic = {c.topic: c for c in reader.connections}
        for topic, kind in ((image_topic, 'Image'), (info_topic, 'CameraInfo')):
            if topic not in by_topic or by_topic[topic].msgtype != f'sensor_msgs/msg/{kind}':
                found = sorted(c.topic for c in reader.connections
                               if c.msgtype == f'sensor_msgs/msg/{kind}')
                raise UsageError(f'{str(args.bag)!r} has no sensor_msgs/{kind} on {topic}: its '
                                 f'{kind} topics are {found or "none"}')
        for connection, _, raw in reader.messages(
                connections=[by_topic[image_topic], by_topic[info_topic]]):
            msg: Any = reader.deserialize(raw, connection.msgtype)
            if connection.topic == info_topic:
                if lens is None:
                    try:
                        lens = Lens(tuple(msg.k), tuple(msg.d))
                    except CameraConfigError as error:
                        raise UsageError(f'{info_topic}: {error}') from None
                    size = (int(msg.width), int(msg.height))
                continue
            try:
                frames.append(image_array(msg, size))
            except CameraConfigError as error:
                raise UsageError(f'{image_topic}: {error}') from None
            if len(frames) >= args.max_frames:
                break
    if lens is None:
        raise UsageError(f'{str(args.bag)!r} has no CameraInfo on {info_topic}')
    try:
        calibration = calibrate(args.camera, frames, lens, target, args.mirrored)
    except CalibrationError as error:
        print(f'omni-micro calibrate-camera: {error}', file=sys.stderr)
        return 1
    plane = calibration.plane
    atomic_text(args.out, calibration.params_yaml(args.mirrored))
    px, py = plane.pixel_size_m
    through = "through the CameraInfo's lens" if lens.calibrated else 'no lens given'
    print(f'{args.camera}: {calibration.corners} points in {calibration.frames} frames '
          f'({through}); '
          f'RMS residual {plane.residual_px:.3g} px, {plane.residual_m * 1e6:.3g} um on the '
          f'platform; pixel {px * 1e6:.4g} x {py * 1e6:.4g} um at the centre, which sees '
          f'({plane.centre_m[0] * 1e3:.4f}, {plane.centre_m[1] * 1e3:.4f}) mm')
    print(f'wrote {args.out}: give it to tracker_node beside your params file '
          f'(--params-file yours.yaml --params-file {args.out})')
    return 0
