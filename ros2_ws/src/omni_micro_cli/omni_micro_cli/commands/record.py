"""`omni-micro record`: a recorder node writing the graph's topics into a rosbag2 bag.

It is what `ros2 bag record --use-sim-time` would be: raw (still serialized) messages, each
stamped with the simulated time at which it arrived, into an mcap (default) or sqlite3 bag with
metadata version 9. Every 0.5 s of wall time the data written so far is pushed to the file, so a
SIGKILL loses at most that much (recover with `omni-micro bag-recover`). The orchestration
starts this as its own process with `run --record BAG`.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_micro_cli.arguments import non_negative_int
from omni_micro_tools.bags import GRAPH_TOPICS, RECORDABLE_TOPICS, STORAGES, check_output_path


def add_storage_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument('--storage', choices=sorted(STORAGES), default='mcap',
                        help="bag storage (default mcap, Jazzy's default)")
    parser.add_argument('--force', action='store_true',
                        help='replace an existing bag at the output path')


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'record', help="record the graph's topics into a rosbag2 bag until Ctrl-C",
        description='Record every topic of the omni-micro graph (or --topics) from the DDS '
                    'domain ROS_DOMAIN_ID (or --domain-id) into a rosbag2 bag, timestamps in '
                    'simulated time. `run --record BAG` does this for you.')
    parser.add_argument('bag', type=Path, metavar='BAG', help='output bag folder (must not exist)')
    parser.add_argument('--topics', nargs='+', metavar='T', choices=sorted(RECORDABLE_TOPICS),
                        help='only these topics (default: all of the graph but the images; '
                             'the images: /camera/<macro|micro>/<image_raw|camera_info>)')
    parser.add_argument('--lockstep-frames', action='store_true',
                        help='report on /lockstep which image frames are written, so that a '
                             'graph in lockstep waits for the recorder as for its tracker and '
                             'no frame is lost however slow the disk')
    parser.add_argument('--domain-id', type=non_negative_int, metavar='N',
                        help='DDS domain to record from (default: $ROS_DOMAIN_ID or 0)')
    add_storage_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_tools.recorder_node import BagRecorder
    from omni_micro_common.node_runtime import run_node

    check_output_path(args.bag, args.force)
    topics = {name: RECORDABLE_TOPICS[name] for name in (args.topics or GRAPH_TOPICS)}

    def finish(recorder: BagRecorder) -> None:
        recorder.close()
        print(f'recorded {sum(recorder.counts.values())} messages into {args.bag}: '
              + ', '.join(f'{topic} {count}' for topic, count in recorder.counts.items()),
              file=sys.stderr)

    # The node runtime stops it on Ctrl-C, SIGTERM or its orchestrator's death, closes the bag
    # (metadata.yaml written) through finish(), and ends the process.
    run_node(lambda: BagRecorder(args.bag, args.storage, topics, args.lockstep_frames),
             config_errors=(),
             on_shutdown=finish, domain_id=args.domain_id)
    return 0
