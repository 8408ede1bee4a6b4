"""`omni-micro preflight`: the bench's live drivers checked before a run, as the graph will read
them (omni_micro_bringup.preflight): one line per finding that needs action, exit 1 if any."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_micro_cli.arguments import domain_id, positive_float, whole_number_in
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import print_json


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'preflight',
        description="Listen to the bench's live drivers for a few seconds, as tracker_node and "
                    'controller_node will, and say what needs fixing before a run: each '
                    "camera's encoding, size, rate sent (by the frames' stamps) and arriving, "
                    'frames lost on the way and why, stamps against this machine\'s clock, '
                    'CameraInfo present and calibrated; each robot\'s joint states arriving, '
                    'their rate and joints; each robot of several named by its code; the QoS '
                    'every driver offers. Exit 0 when nothing needs action, 1 when something '
                    'does (one line each), 2 on bad input. docs/images.md, "The bench".')
    parser.add_argument('--camera', action='append', default=[], metavar='NAME[=TOPIC]',
                        help="a tracker camera to check (macro, micro), its image topic "
                             "optional (its CameraInfo beside it); again for more (default: "
                             "the tracker's cameras and topics from its params)")
    parser.add_argument('--params', type=Path, action='append', default=[], metavar='FILE',
                        help="tracker_node's params file as you will give it (cameras, "
                             'topics, resolution, calibration); again for more')
    parser.add_argument('--robots', type=whole_number_in(0, 42, ' (robots)'), default=1,
                        metavar='N',
                        help='robots on the bench: 1 (default) the single robot on '
                             '/joint_states; N > 1 robot_0 .. robot_N-1 on '
                             '/robot_k/joint_states, each to be named by its code; 0 cameras '
                             'only')
    parser.add_argument('--duration', type=positive_float, default=5.0, metavar='S',
                        help='seconds to listen (default 5)')
    parser.add_argument('--domain-id', type=domain_id, metavar='N',
                        help="the drivers' DDS domain (default: $ROS_DOMAIN_ID or 0)")
    parser.add_argument('--json', action='store_true',
                        help='print the figures and the findings as one JSON object')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_bringup.params_files import check_params_file, params_from_files
    from omni_micro_bringup.preflight import CameraWatch, RobotWatch, naming_findings
    from omni_micro_common.topic_names import (
        JOINT_STATES_TOPIC,
        camera_info_beside,
        robot_name,
        robot_topic,
    )
    from omni_micro_vision.errors import CameraConfigError
    from omni_micro_vision.tracked_camera import tracked_camera

    for path in args.params:
        check_params_file(path)
    values = params_from_files('tracker_node', *args.params)
    chosen = dict(item.split('=', 1) if '=' in item else (item, '') for item in args.camera)
    cameras_param = values.get('cameras', ['macro', 'micro'])
    names = list(chosen) or [str(name) for name in (
        cameras_param if isinstance(cameras_param, list) else [])]
    tracked, cameras = {}, []
    for name in names:
        try:
            tracked[name] = tracked_camera(name, values.get)
        except CameraConfigError as error:
            raise UsageError(f'--camera {name}: {error}') from None
        topic = chosen.get(name) or str(values.get(f'{name}.image_topic',
                                                   f'/camera/{name}/image_raw'))
        info = (camera_info_beside(topic) if chosen.get(name) else
                str(values.get(f'{name}.info_topic', camera_info_beside(topic))))
        columns, rows = tracked[name].plane.resolution_px
        cameras.append(CameraWatch(name, topic, info, (int(columns), int(rows))))
    robot_names = [robot_name(k) for k in range(args.robots)] if args.robots > 1 else []
    robots = ([RobotWatch('robot', JOINT_STATES_TOPIC)] if args.robots == 1 else
              [RobotWatch(robot_name(k), robot_topic(k, JOINT_STATES_TOPIC))
               for k in range(len(robot_names))])

    from omni_micro_bringup.preflight_probe import listen

    if not args.json:
        print(f'listening {args.duration:g} s to {len(cameras)} camera(s) and '
              f'{len(robots)} robot(s)...', file=sys.stderr, flush=True)
    listen(cameras, robots, args.duration, args.domain_id, tracked, robot_names)
    findings = [line for camera in cameras for line in camera.findings(args.duration)]
    findings += [line for robot in robots for line in robot.findings(args.duration)]
    findings += naming_findings(robot_names, cameras)
    if args.json:
        print_json({'cameras': [camera.summary(args.duration) for camera in cameras],
                    'robots': [robot.summary() for robot in robots], 'findings': findings,
                    'ok': not findings})
    else:
        for camera in cameras:
            print(_camera_line(camera.summary(args.duration)))
        for robot in robots:
            print(_robot_line(robot.summary()))
        for line in findings:
            print(f'needs action: {line}')
        if not findings:
            print('nothing needs action')
    return 1 if findings else 0


def _camera_line(seen: dict) -> str:
    if not seen['frames']:
        return f"{seen['camera']} ({seen['image_topic']}): no frames"
    lost = f"{seen['frames_lost']} of {seen['frames_sent']} lost" if seen['frames_sent'] else ''
    return (f"{seen['camera']} ({seen['image_topic']}): {seen['encoding']} "
            f"{seen['size'][0]} x {seen['size'][1]}, {seen['sent_hz'] or '?'} Hz sent, "
            f"{seen['arriving_hz']} Hz arriving{', ' + lost if lost else ''}, stamps "
            f"{(seen['age_s'] or 0.0) * 1e3:.1f} ms old on arrival, CameraInfo "
            + ('calibrated' if seen['calibrated'] else 'uncalibrated' if seen['camera_info']
               else 'missing')
            + f"; QoS {'; '.join(seen['qos_offered']) or 'none'}")


def _robot_line(seen: dict) -> str:
    if not seen['states']:
        return f"{seen['robot']} ({seen['topic']}): no joint states"
    return (f"{seen['robot']} ({seen['topic']}): {seen['rate_hz']} Hz, joints "
            f"{', '.join(seen['joints'])}; QoS {'; '.join(seen['qos_offered']) or 'none'}")
