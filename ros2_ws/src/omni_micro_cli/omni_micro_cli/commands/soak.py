"""`omni-micro soak`: one graph, many goals in a row, recorded; memory and message counts."""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

from omni_micro_bringup.graph import run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_cli.arguments import (
    add_steering_argument,
    seed_number,
    steering_overrides,
    whole_number_in,
)
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.graph_arguments import (
    add_timing_arguments,
    add_view_arguments,
    check_timing,
    view_from_args,
)
from omni_micro_cli.outputs import echo_to_stderr, output_folder, print_json
from omni_micro_tools.topics import RECORDABLE_TOPICS
from omni_micro_vision.camera import DEFAULT_RIG

# Goals inside the micro camera's field (so each one can be reached to the 3 um tolerance),
# kept 0.2 mm from its edges so that a move's slip cannot carry the robot out of view.
MARGIN_M = 0.2e-3


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'soak',
        description='Start the graph once with the robot on the micro work platform, send '
                    '--goals random goals (seeded) one after the other, record everything, and '
                    "report every process's memory growth and whether the bag holds exactly "
                    'the messages the nodes say they published. Exit 0 when every goal was '
                    'reached and no message is missing, 1 otherwise, 2 for a bad argument.')
    parser.add_argument('--goals',
                        type=whole_number_in(0, 100_000), default=50, metavar='N',
                        help='how many random goals, one after the other (default 50)')
    add_timing_arguments(parser, default_rtf='max')
    add_steering_argument(parser)
    parser.add_argument('--seed', type=seed_number, default=1, metavar='N',
                        help='seed of the goals and of the camera noise (default 1)')
    parser.add_argument('--out', type=output_folder, default='out/soak', metavar='DIR',
                        help='the bag, logs and report go into a new folder here')
    parser.add_argument('--json', action='store_true',
                        help='standard output: the report as one JSON object alone (the rest '
                             'on stderr)')
    parser.add_argument('--quiet', action='store_true',
                        help="do not echo the nodes' logs (they are still kept)")
    add_view_arguments(parser, flag=True)
    parser.set_defaults(handler=run)


def random_goals(count: int, seed: int) -> list[tuple[float, float]]:
    micro = DEFAULT_RIG.micro
    rng = np.random.default_rng(seed)
    half = np.array(micro.field_m) / 2 - MARGIN_M
    goals = np.array(micro.center_m) + rng.uniform(-half, half, size=(count, 2))
    return [(float(x), float(y)) for x, y in goals]


def run(args: argparse.Namespace) -> int:
    from omni_micro_tools.bag_reading import bag_message_counts

    try:
        check_timing(args)
    except argparse.ArgumentTypeError as error:
        raise UsageError(str(error)) from None
    if args.goals < 1:
        raise UsageError(f'--goals must be at least 1, got {args.goals}')
    folder = args.out / time.strftime('%Y%m%d-%H%M%S')
    folder.mkdir(parents=True, exist_ok=False)
    bag = folder / 'bag'
    goals = random_goals(args.goals, args.seed)
    result = run_graph(GraphOptions(
        goal_m=goals[0], more_goals_m=goals[1:], seed=args.seed, real_time_factor=args.rtf,
        lockstep=not args.free_running,
        log_dir=folder / 'logs', record=bag, record_whole=True, timeout_s=600.0,
        dynamics_overrides={'initial_pose': [*DEFAULT_RIG.micro.center_m, 0.0],
                            **steering_overrides(args.steering)},
        echo=None if args.quiet else echo_to_stderr, view=view_from_args(args)))
    reached = sum(1 for status in result.goals if status['outcome'] == 'reached')
    recorded = bag_message_counts(bag)
    # Of the recorded topics (the throttled copies of /odom and /joint_states are not).
    missing = {topic: count - recorded.get(topic, 0) for topic, count in result.published.items()
               if topic in RECORDABLE_TOPICS and recorded.get(topic, 0) != count}
    # Growth after a warm-up of five goals (imports, caches and DDS pools fill up first).
    warm = min(5, len(next(iter(result.memory_kb.values()), [])) - 1)
    growth = {name: {'after_warm_up_kb': sizes[warm], 'end_kb': sizes[-1],
                     'growth_kb': sizes[-1] - sizes[warm]}
              for name, sizes in result.memory_kb.items()}
    report = {'goals': args.goals, 'reached': reached, 'sim_time_s': result.sim_time_s,
              'wall_time_s': result.wall_time_s, 'memory': growth, 'published': result.published,
              'recorded': recorded, 'missing_from_bag': missing, 'bag': str(bag)}
    (folder / 'report.json').write_text(json.dumps(report, indent=2))
    print(f'{reached}/{args.goals} goals reached in {result.sim_time_s:.1f} s simulated, '
          f'{result.wall_time_s:.1f} s wall', file=sys.stderr)
    for name, sizes in growth.items():
        print(f'  {name:16s} RSS {sizes["after_warm_up_kb"] / 1024:7.1f} MB after 5 goals, '
              f'{sizes["end_kb"] / 1024:7.1f} MB at the end ({sizes["growth_kb"]:+d} kB)',
              file=sys.stderr)
    print(f'  bag: {sum(recorded.values())} messages; missing against what was published: '
          f'{missing or "none"}', file=sys.stderr)
    if args.json:
        print_json(report)
    if reached != args.goals or missing:
        raise RunFailed(f'{reached}/{args.goals} goals reached; missing from the bag: {missing}')
    return 0
