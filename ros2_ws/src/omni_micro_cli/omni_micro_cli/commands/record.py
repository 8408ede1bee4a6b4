"""`omni-micro record`: omni_micro_tools' bag_recorder node, from the command line.

``run --record BAG`` starts the same node as a process of the graph.
"""

from __future__ import annotations

import argparse

from omni_micro_cli.arguments import domain_id
from omni_micro_cli.graph_arguments import add_storage_arguments
from omni_micro_cli.outputs import output_folder
from omni_micro_tools.topics import GRAPH_TOPICS, RECORDABLE_TOPICS


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'record',
        description='Record every topic of the omni-micro graph (or --topics) from the DDS '
                    'domain ROS_DOMAIN_ID (or --domain-id) into a rosbag2 bag, timestamps in '
                    'simulated time. `run --record BAG` does this for you.')
    parser.add_argument('bag', type=output_folder, metavar='BAG',
                        help='output bag folder (must not exist)')
    parser.add_argument('--topics', nargs='+', metavar='T', choices=sorted(RECORDABLE_TOPICS),
                        help='only these topics (default: all of the graph but the images; '
                             'the images: /camera/<macro|micro>/<image_raw|camera_info>)')
    parser.add_argument('--lockstep-frames', action='store_true',
                        help='report on /lockstep which image frames are written, so that a '
                             'graph in lockstep waits for the recorder as for its tracker and '
                             'no frame is lost however slow the disk')
    parser.add_argument('--whole', action='store_true',
                        help="keep every message received until stopped (default: when "
                             "stopped, the bag is put in the order of simulated time and ends "
                             "0.5 s after the run's last outcome, so the same run gives the "
                             'same file; docs/graph.md, "Same seed, same bag")')
    parser.add_argument('--domain-id', type=domain_id, metavar='N',
                        help='DDS domain to record from (default: $ROS_DOMAIN_ID or 0)')
    add_storage_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from rclpy.parameter import Parameter

    from omni_micro_common.node_runtime import run_node
    from omni_micro_tools.bags import check_bag_output
    from omni_micro_tools.recorder_node import BagRecorder, report_and_close

    check_bag_output(args.bag, args.force)
    overrides = [Parameter('bag', value=str(args.bag)), Parameter('storage', value=args.storage),
                 Parameter('topics', value=list(args.topics or GRAPH_TOPICS)),
                 Parameter('lockstep_frames', value=bool(args.lockstep_frames)),
                 Parameter('end_at_outcome', value=not args.whole)]
    run_node(lambda: BagRecorder(parameter_overrides=overrides), config_errors=(),
             on_shutdown=report_and_close, domain_id=args.domain_id)
    return 0
