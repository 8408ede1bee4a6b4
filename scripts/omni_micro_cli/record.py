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
import time
from pathlib import Path

from omni_micro_cli.arguments import non_negative_int
from omni_micro_cli.bags import GRAPH_TOPICS, STORAGES, check_output_path, flush, open_writer

FLUSH_PERIOD_S = 0.5


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
    parser.add_argument('--topics', nargs='+', metavar='T', choices=sorted(GRAPH_TOPICS),
                        help='only these topics (default: all of the graph)')
    parser.add_argument('--domain-id', type=non_negative_int, metavar='N',
                        help='DDS domain to record from (default: $ROS_DOMAIN_ID or 0)')
    add_storage_arguments(parser)
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.clock import Clock, ClockType
    from rclpy.node import Node
    from rclpy.parameter import Parameter
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    from omni_micro_cli.graph import message_class

    check_output_path(args.bag, args.force)
    topics = {name: GRAPH_TOPICS[name] for name in (args.topics or GRAPH_TOPICS)}
    # Ctrl-C and SIGTERM arrive as KeyboardInterrupt (cli.main), with the context still valid.
    rclpy.init(domain_id=args.domain_id, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('bag_recorder', parameter_overrides=[Parameter('use_sim_time', value=True)])
    writer, connections = open_writer(args.bag, args.storage, topics)
    counts = dict.fromkeys(topics, 0)

    def record(topic: str):
        connection = connections[topic]

        def on_message(data: bytes) -> None:
            writer.write(connection, node.get_clock().now().nanoseconds, data)
            counts[topic] += 1
        return on_message

    for topic, spec in topics.items():
        qos = QoSProfile(depth=spec.depth, reliability=ReliabilityPolicy.RELIABLE,
                         durability=(DurabilityPolicy.TRANSIENT_LOCAL if spec.latched
                                     else DurabilityPolicy.VOLATILE))
        node.create_subscription(message_class(spec.msgtype), topic, record(topic), qos,
                                 raw=True)
    subscriptions = list(node.subscriptions)
    status_pub = node.create_publisher(DiagnosticStatus, '/bag_recorder/status', QoSProfile(
        depth=1, reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL))
    announced = []
    last_flush = [time.monotonic()]

    def on_wall_timer() -> None:
        if time.monotonic() - last_flush[0] >= FLUSH_PERIOD_S:
            flush(writer)
            last_flush[0] = time.monotonic()
        # "recording" once every recorded topic has a matched publisher, so that whoever starts
        # the graph's clock knows nothing will be missed from the beginning.
        if not announced and all(sub.get_publisher_count() > 0 for sub in subscriptions
                                 if sub.topic_name in topics and sub.topic_name != '/goal_pose'):
            status_pub.publish(DiagnosticStatus(level=DiagnosticStatus.OK, name='bag_recorder',
                                                message='recording'))
            announced.append(True)

    node.create_timer(0.1, on_wall_timer,
                      clock=Clock(clock_type=ClockType.STEADY_TIME))
    node.get_logger().info(f'recording {len(topics)} topics into {args.bag} ({args.storage})')
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    except RuntimeError:
        # An interrupt inside rclpy's message conversion surfaces as a RuntimeError.
        pass
    finally:
        writer.close()   # writes metadata.yaml: the bag is complete
        node.destroy_node()
        rclpy.try_shutdown()
    print(f'recorded {sum(counts.values())} messages into {args.bag}: '
          + ', '.join(f'{topic} {count}' for topic, count in counts.items()), file=sys.stderr)
    return 0
