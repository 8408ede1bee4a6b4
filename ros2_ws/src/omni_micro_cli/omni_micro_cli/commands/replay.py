"""`omni-micro replay BAG`: publish a bag's messages again with their original spacing."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from omni_micro_cli.arguments import (
    FACTOR_RANGE,
    domain_id,
    non_negative_int,
    number_in,
    positive_float,
)
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_common.clocks import is_wall_clock
from omni_micro_common.lockstep import REPLAY_SYNC_WINDOW
from omni_micro_common.topic_names import CLOCK_TOPIC

if TYPE_CHECKING:
    from omni_micro_tools.bag_reading import BagMessages


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
    parser.add_argument('--robot', type=non_negative_int, metavar='K',
                        help='of a fleet\'s bag (omni-micro fleet --record): robot K\'s topics '
                             '(/robot_K/odom, ...) under the single robot\'s names (/odom, ...); '
                             '--topics then names those')
    parser.add_argument('--loop', action='store_true', help='start again at the end, until Ctrl-C')
    parser.add_argument('--wait-subscribers', type=positive_float, metavar='S',
                        help='first wait up to S seconds until every replayed topic has a '
                             'subscriber')
    parser.add_argument('--sync', nargs='+', metavar='NODE', default=[],
                        help='wait for these nodes (e.g. vision_node) to report on /lockstep '
                             'that they have handled each message before sending more than '
                             f'{REPLAY_SYNC_WINDOW} ahead: a node that cannot keep up then loses '
                             'nothing (the original spacing is kept when they are faster)')
    parser.add_argument('--domain-id', type=domain_id, metavar='N',
                        help='DDS domain (default: $ROS_DOMAIN_ID or 0)')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_common.topic_names import robot_index, robot_name
    from omni_micro_tools.bag_reading import bag_topics, read_bag

    available = bag_topics(args.bag)
    prefix = '' if args.robot is None else f'/{robot_name(args.robot)}'
    if prefix and not any(topic.startswith(prefix + '/') for topic in available):
        robots = sorted({topic.split('/')[1] for topic in available
                         if robot_index(topic.split('/')[1]) is not None})
        raise UsageError(f'--robot {args.robot}: the bag has no {prefix}/ topics (its robots: '
                         f'{", ".join(robots) or "none, not a fleet bag"})')
    if prefix:
        topics = ([prefix + topic for topic in args.topics] if args.topics
                  else [t for t in available if t.startswith(prefix + '/')])
    else:
        topics = args.topics or [t for t in available if t != CLOCK_TOPIC]
    unknown = sorted(set(topics) - set(available))
    if unknown:
        raise UsageError(f'topic(s) {unknown} are not in the bag; it has {available}')
    if args.clock and CLOCK_TOPIC not in topics:
        if CLOCK_TOPIC not in available:
            raise UsageError('--clock: the bag has no /clock (a run with a real robot has none: '
                             'its messages carry the wall clock)')
        topics.append(CLOCK_TOPIC)
    # Only what is replayed is read: a bag with images holds a megabyte a frame.
    data = read_bag(args.bag, topics=topics, decode=bool(args.sync))
    if not any(data.timestamps[topic] for topic in topics):
        raise UsageError(f'no messages to replay on {topics}')
    first = min(stamps[0] for stamps in data.timestamps.values() if stamps)
    if CLOCK_TOPIC not in available and is_wall_clock(first * 1e-9):
        print(f'{args.bag}: recorded on the wall clock (a run with a real robot: no /clock, no '
              '/odom); its messages go out with the stamps they were recorded with',
              file=sys.stderr)

    from omni_micro_tools.bag_player import BagPlayer
    from omni_micro_tools.errors import ReplayError

    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    if prefix:
        data, topics = _as_one_robot(data, topics, prefix)
    player = BagPlayer(data, topics, args.sync, args.domain_id)
    total = len(player.events)
    print(f'replaying {total} messages on {len(topics)} topics from {args.bag}: '
          f'{player.duration_s:.2f} s of the bag at --rate {args.rate:g}, about '
          f'{player.duration_s / args.rate:.1f} s' + (', again and again (--loop)'
                                                      if args.loop else ''), file=sys.stderr)
    shown = False   # a progress line is drawn: what follows starts on a line of its own

    def progress(done: int, at_s: float) -> None:
        nonlocal shown
        shown = True
        print(f'\r  {done}/{total} messages, {at_s:.1f}/{player.duration_s:.1f} s of the bag',
              end='', file=sys.stderr, flush=True)

    try:
        if args.wait_subscribers:
            player.wait_for_subscribers(args.wait_subscribers)
        player.play(args.rate, args.loop, on_progress=progress if sys.stderr.isatty() else None)
    except ReplayError as error:
        raise RunFailed(str(error)) from None
    except KeyboardInterrupt:
        # Exit 130 as every command interrupted does, having said how far it went.
        print(f'{NEWLINE if shown else ""}interrupted after {player.published} of {total} '
              f'messages', file=sys.stderr)
        raise
    finally:
        player.close()
    print(f'{NEWLINE if shown else ""}replayed {player.published} messages on '
          f'{len(topics)} topics', file=sys.stderr)
    return 0


NEWLINE = '\n'


def _as_one_robot(data: BagMessages, topics: list[str],
                  prefix: str) -> tuple[BagMessages, list[str]]:
    """The bag's messages with one robot's topics renamed to the single robot's."""
    from omni_micro_tools.bag_reading import BagMessages

    def renamed(topic: str) -> str:
        return topic[len(prefix):] if topic.startswith(prefix + '/') else topic

    return (BagMessages({renamed(topic): value for topic, value in data.timestamps.items()},
                        {renamed(topic): value for topic, value in data.messages.items()},
                        {renamed(topic): value for topic, value in data.raw.items()},
                        {renamed(topic): value for topic, value in data.msgtypes.items()}),
            [renamed(topic) for topic in topics])
