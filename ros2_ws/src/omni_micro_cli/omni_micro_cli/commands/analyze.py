"""`omni-micro analyze BAG --out DIR`: figures and a summary of a recorded run, from its bag."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from omni_micro_cli.arguments import positive_int, whole_number_in
from omni_micro_cli.outputs import output_folder, staged_directory

# An animation's frames are held in memory until written (~1.4 MB each at 1000 x 450 px).
MAX_FRAMES = 2000


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'analyze',
        description='From a bag alone: the route against the ideal straight route (Figs. 8(c), '
                    '11) with the capture points, each wheel\'s longitudinal and transverse slip '
                    'against time (Fig. 8(a)(b)), the distance left after each period, and a '
                    'summary (final deviation, periods, duration, outcome) as JSON and markdown.')
    parser.add_argument('bag', type=Path, metavar='BAG', help='a bag recorded with --record')
    parser.add_argument('--out', type=output_folder, required=True, metavar='DIR',
                        help='folder for the figures and summary (made if missing; files of '
                             'the same names are replaced, each whole, other files are kept)')
    parser.add_argument('--animate', choices=('gif', 'mp4'), nargs='?', const='gif',
                        metavar='gif|mp4',
                        help='also render the run as DIR/run.gif (or .mp4, needs ffmpeg) and '
                             'its last frame as DIR/run_last_frame.png: the route forming, '
                             'captures landing, a micro-field inset, simulated time shown; '
                             'of a fleet\'s bag, every robot in its colour, labelled')
    parser.add_argument('--frames', type=whole_number_in(1, MAX_FRAMES), default=100,
                        metavar='N',
                        help='frames of the animation, evenly spaced in simulated time '
                             f'(default 100, at most {MAX_FRAMES}: the writer holds them)')
    parser.add_argument('--fps', type=positive_int, default=10, metavar='F',
                        help='frames per second of the animation (default 10)')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_studies import paper_figures as plots
    from omni_micro_tools.bag_reading import bag_topics, check_readable_bag
    from omni_micro_tools.fleet_analysis import fleet_robots
    from omni_micro_tools.robot_analysis import summarize_run, summary_markdown

    check_readable_bag(args.bag)
    robots = fleet_robots(bag_topics(args.bag))
    if robots:
        return analyze_fleet(args, robots)
    summary, arrays = summarize_run(args.bag)
    if summary['route_from'] == 'captures':
        print(f'{args.bag}: no /odom (a run with a real robot, whose true pose nobody knows): '
              'the route is where the cameras saw it', file=sys.stderr)
    route, goal = arrays['route'], arrays['goal']
    with staged_directory(args.out) as scratch:
        ideal = np.array([route[0, 1:], goal])
        label = ('as the cameras saw it' if summary['route_from'] == 'captures'
                 else 'recorded route')
        plots.routes(scratch / 'route.png', {label: route[:, 1:]}, ideal_m=ideal,
                     goal_m=goal, captures_m=arrays['captures'][:, 1:],
                     title='route against the ideal straight route (from the bag)')
        if len(arrays['slip']):
            slip = arrays['slip']
            plots.wheel_slip(scratch / 'slip_longitudinal.png', slip[:, 0], slip[:, 1::2],
                             component='longitudinal', title='longitudinal slip of each wheel')
            plots.wheel_slip(scratch / 'slip_transverse.png', slip[:, 0], slip[:, 2::2],
                             component='transverse', title='transverse slip of each wheel')
        if len(arrays['remaining']):
            plots.remaining_distance(scratch / 'periods.png', arrays['remaining'])
        if args.animate:
            from omni_micro_vision.animation import animate

            animate(args.bag, scratch / f'run.{args.animate}', args.frames, args.fps,
                    scratch / 'run_last_frame.png')
        (scratch / 'summary.json').write_text(json.dumps(summary, indent=2))
        (scratch / 'summary.md').write_text(summary_markdown(summary))
    print(summary_markdown(summary))
    print(f'figures and summary in {args.out}/', file=sys.stderr)
    return 0


def analyze_fleet(args: argparse.Namespace, robots: list[int]) -> int:
    """A fleet's bag: a table per robot and every robot's route in one figure."""
    from omni_micro_tools.fleet_analysis import fleet_markdown, summarize_fleet
    from omni_micro_vision.fleet_figure import DrawnRobot, fleet_routes_png

    summary, drawn = summarize_fleet(args.bag, robots)
    with staged_directory(args.out) as scratch:
        (scratch / 'route.png').write_bytes(fleet_routes_png(
            [DrawnRobot(k, row['robot'], drawn[row['robot']]['route_m'],
                        drawn[row['robot']]['goals_m'], row['goals_reached'])
             for k, row in zip(robots, summary['robots'], strict=True)],
            f'{len(robots)} robots (from {args.bag.name})', goal_word='goal pose'))
        if args.animate:
            from omni_micro_vision.animation import animate

            animate(args.bag, scratch / f'run.{args.animate}', args.frames, args.fps,
                    scratch / 'run_last_frame.png', robots=robots)
        (scratch / 'summary.json').write_text(json.dumps(summary, indent=2))
        (scratch / 'summary.md').write_text(fleet_markdown(summary))
    print(fleet_markdown(summary))
    print(f'figures and summary in {args.out}/', file=sys.stderr)
    return 0
