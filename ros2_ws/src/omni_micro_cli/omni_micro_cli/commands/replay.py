"""`omni-micro replay BAG`: publish a bag's messages again with their original spacing."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from omni_micro_cli.arguments import FACTOR_RANGE, domain_id, number_in, positive_float
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_tools.topics import RECORDABLE_TOPICS


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'replay',
        description='Publish the messages of a bag on their topics with their original '
                    'spacing divided by --rate, into the DDS domain ROS_DOMAIN_ID (or '
                    '--domain-id), loopback only. /clock is replayed only with --clock, so '
                    'that nodes with use_sim_time follow the bag. Example: replay /odom into a '
                    'vision_node to get the captures again.')
    parser.add_argument('bag', type=Path, metavar='BAG', help='the folder of a recorded bag')
    parser.add_argument('--rate', type=number_in(*FACTOR_RANGE), default=1.0, metavar='R',
                        help='speed-up of the original spacing (default 1; 0.001 to 10000)')
    parser.add_argument('--topics', nargs='+', metavar='T',
                        help='only these topics (default: every topic but /clock)')
    parser.add_argument('--clock', action='store_true', help='also publish the recorded /clock')
    parser.add_argument('--loop', action='store_true', help='start again at the end, until Ctrl-C')
    parser.add_argument('--wait-subscribers', type=positive_float, metavar='S',
                        help='first wait up to S seconds until every replayed topic has a '
                             'subscriber')
    parser.add_argument('--sync', nargs='+', metavar='NODE', default=[],
                        help='wait for these nodes (e.g. vision_node) to report on /lockstep '
                             'that they have handled each message before sending more than '
                             f'{SYNC_WINDOW} ahead: a node that cannot keep up then loses '
                             'nothing (the original spacing is kept when they are faster)')
    parser.add_argument('--domain-id', type=domain_id, metavar='N',
                        help='DDS domain (default: $ROS_DOMAIN_ID or 0)')
    parser.set_defaults(handler=run)


# With --sync: how many stamped messages may be sent beyond what the slowest node handled.
SYNC_WINDOW = 10


def header_stamp_ns(msg: object) -> int | None:
    from omni_micro_common.conventions import stamp_ns

    header = getattr(msg, 'header', None)
    return None if header is None else stamp_ns(header.stamp)


def run(args: argparse.Namespace) -> int:
    from omni_micro_tools.bag_reading import bag_topics, read_bag

    available = bag_topics(args.bag)
    topics = args.topics or [t for t in available if t != '/clock']
    unknown = sorted(set(topics) - set(available))
    if unknown:
        raise UsageError(f'topic(s) {unknown} are not in the bag; it has {available}')
    if args.clock and '/clock' not in topics:
        if '/clock' not in available:
            raise UsageError('--clock: the bag has no /clock')
        topics.append('/clock')
    # Only what is replayed is read: a bag with images holds a megabyte a frame.
    data = read_bag(args.bag, topics=topics, decode=bool(args.sync))
    events = sorted((stamp, topic, index) for topic in topics
                    for index, stamp in enumerate(data.timestamps[topic]))
    if not events:
        raise UsageError(f'no messages to replay on {topics}')

    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    from omni_micro_common.errors import LockstepError
    from omni_micro_common.lockstep import ACK_TOPIC
    from omni_micro_common.lockstep_reporting import LOCKSTEP_QOS, decode_ack
    from omni_micro_common.messages import message_class

    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    rclpy.init(domain_id=args.domain_id)
    node = Node('bag_replay')
    publishers = {}
    for topic in topics:
        spec = RECORDABLE_TOPICS.get(topic)
        # A latched topic deep enough that no message is replaced before a reader has it (a
        # status of depth 1 sent twice in quick succession at --rate 20 lost the first); the
        # others keep their depth (camera frames are paced by it).
        qos = QoSProfile(depth=(max(spec.depth, 1000) if spec.latched else spec.depth)
                         if spec else 1000,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=(DurabilityPolicy.TRANSIENT_LOCAL if spec and spec.latched
                                     else DurabilityPolicy.VOLATILE))
        publishers[topic] = node.create_publisher(message_class(data.msgtypes[topic]), topic, qos)
    handled: dict[str, int] = {}

    def on_report(msg: DiagnosticStatus) -> None:
        try:
            ack = decode_ack(msg)
        except LockstepError:
            return
        if ack is not None and ack.node in args.sync:
            # A tracker reads no odometry: what it handled is the frames.
            done = ack.processed_ns if ack.processed_ns is not None else ack.frame_handled_ns
            if done is not None:
                handled[ack.node] = max(handled.get(ack.node, -1), done)

    executor = SingleThreadedExecutor()
    executor.add_node(node)
    sent_stamps: list[int] = []
    if args.sync:
        node.create_subscription(DiagnosticStatus, ACK_TOPIC, on_report, LOCKSTEP_QOS)

    def wait_for_sync(behind: int) -> None:
        """Until every --sync node handled the message sent ``behind`` stamped ones ago."""
        if not args.sync or len(sent_stamps) < behind:
            return
        needed = sent_stamps[-behind]
        deadline = time.monotonic() + 30.0
        while any(handled.get(name, -1) < needed for name in args.sync):
            if time.monotonic() > deadline:
                raise RunFailed(f'--sync: {sorted(set(args.sync) - set(handled)) or args.sync} '
                                f'reported nothing on /lockstep for 30 s (is it running, in '
                                f'this domain?)')
            executor.spin_once(timeout_sec=0.05)

    published = 0
    try:
        if args.wait_subscribers:
            deadline = time.monotonic() + args.wait_subscribers
            while any(p.get_subscription_count() == 0 for p in publishers.values()):
                if time.monotonic() > deadline:
                    lonely = [t for t, p in publishers.items() if p.get_subscription_count() == 0]
                    raise RunFailed(f'no subscriber on {lonely} after {args.wait_subscribers} s')
                time.sleep(0.05)
            time.sleep(0.5)   # discovery shows a reader a little before it is matched
        while True:
            first = events[0][0]
            started = time.monotonic()
            for stamp, topic, index in events:
                delay = (stamp - first) * 1e-9 / args.rate - (time.monotonic() - started)
                if delay > 0:
                    time.sleep(delay)
                wait_for_sync(SYNC_WINDOW)
                publishers[topic].publish(data.raw[topic][index])
                published += 1
                if args.sync:
                    header_ns = header_stamp_ns(data.messages[topic][index])
                    if header_ns is not None:
                        sent_stamps.append(header_ns)
            if not args.loop:
                break
        wait_for_sync(1)
        time.sleep(0.5)   # let reliable writers hand over the tail before the node goes
    except KeyboardInterrupt:
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    print(f'replayed {published} messages on {len(topics)} topics', file=sys.stderr)
    return 0
