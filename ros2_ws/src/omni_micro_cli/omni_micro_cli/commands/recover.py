"""`omni-micro bag-recover BAG`: a readable bag from one whose recorder was killed."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_micro_cli.outputs import output_folder
from omni_micro_tools.topics import STORAGE_NAMES


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bag-recover',
        description='A recorder killed with SIGKILL leaves a bag without metadata.yaml (and an '
                    'mcap file without its footer), which readers refuse; a copy cut short or a '
                    'bad disk leaves a file with damaged parts. This copies every intact '
                    'message into a new bag (default BAG-recovered), the intact chunks after a '
                    'damaged one too, skipping damaged chunks and messages that do not decode, '
                    'and says how many it dropped and between which times. The recorder pushes '
                    'its data to the file every 0.5 s, so a kill loses at most that much. The '
                    'copy is in the order of the messages\' time, as a finished bag is; from a '
                    'file its recorder did not finish, without its last 1 s (which may have been '
                    'incomplete): a prefix of the bag the run would have recorded.')
    parser.add_argument('bag', type=Path, metavar='BAG',
                        help='the folder of a damaged bag, or of one whose recorder was killed '
                             '(an .mcap or .db3 file, with or without metadata.yaml)')
    parser.add_argument('--out', type=output_folder, metavar='DIR', help='default: BAG-recovered')
    parser.add_argument('--storage', choices=sorted(STORAGE_NAMES), default='mcap',
                        help='storage of the recovered bag (default mcap)')
    parser.add_argument('--keep-unsure-tail', action='store_true',
                        help='keep the last 1 s of simulated time too (a short bag may be '
                             'nothing else; then it may not be a prefix of the finished bag)')
    parser.add_argument('--force', action='store_true', help='replace an existing --out bag')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_tools.bag_order import RECOVERY_WINDOW_S
    from omni_micro_tools.bags import check_bag_output, recover

    target = args.out or args.bag.with_name(args.bag.name + '-recovered')
    check_bag_output(target, args.force)
    report = recover(args.bag, target, args.storage, keep_unsure_tail=args.keep_unsure_tail)
    print(f'recovered {report.kept} messages into {target}: '
          + ', '.join(f'{topic} {count}' for topic, count in sorted(report.counts.items())),
          file=sys.stderr)
    if report.dropped or report.damaged_chunks or report.cut_short:
        where = [stretch.said() for stretch in report.stretches]
        if report.undecodable:
            where.append(f'{report.undecodable} read whole that did not decode as their type')
        print(f'dropped {report.dropped} messages' + (f': {"; ".join(where)}' if where else '')
              + ('; the file ends mid-record (cut short): what followed is lost'
                 if report.cut_short else ''), file=sys.stderr)
    if report.unsure_tail:
        print(f'left out the last {RECOVERY_WINDOW_S:g} s of simulated time '
              f'({report.unsure_tail} messages), which may have been incomplete when the '
              'recorder stopped: what is kept is a prefix of the bag the run would have recorded',
              file=sys.stderr)
    return 0
