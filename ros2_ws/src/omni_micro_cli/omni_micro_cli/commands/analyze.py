"""`omni-micro analyze BAG --out DIR`: figures and a summary of a recorded run, from its bag."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from omni_micro_cli.arguments import positive_int, whole_number_in
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import output_folder, staged_directory
from omni_micro_common.clocks import is_wall_clock
from omni_micro_common.topic_names import (
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    CONTROLLER_STATUS_TOPIC,
    GOAL_TOPIC,
    ODOM_TOPIC,
    WHEEL_SLIP_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
)
from omni_micro_control.feedback import OUTCOME_NAMES

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


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def summarize(bag: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The run's numbers and the arrays the figures need."""
    from omni_micro_tools.bag_reading import read_bag

    data = read_bag(bag)
    route, seen_only = route_of(data.messages)
    if not len(route):
        raise UsageError(f'{str(bag)!r} has no /odom and no captures: nothing to analyse')
    if seen_only:
        print(f'{bag}: no /odom (a run with a real robot, whose true pose nobody knows): the '
              'route is where the cameras saw it', file=sys.stderr)
    statuses = [{'message': m.message, **{kv.key: kv.value for kv in m.values}}
                for m in data.messages.get(CONTROLLER_STATUS_TOPIC, [])]
    goals = data.messages.get(GOAL_TOPIC, [])
    goal = None
    if goals:
        goal = (goals[-1].pose.position.x, goals[-1].pose.position.y)
    else:
        with_goal = [s for s in statuses if 'goal_x_m' in s]
        if with_goal:
            goal = (float(with_goal[-1]['goal_x_m']), float(with_goal[-1]['goal_y_m']))
    captures = np.array([(_stamp(m), m.pose.position.x, m.pose.position.y)
                         for topic in CAPTURE_TOPICS.values()
                         for m in data.messages.get(topic, [])]).reshape(-1, 3)
    moves = [m for m in data.messages.get(WHEEL_TRAJECTORY_TOPIC, []) if m.points]
    slip_msgs = data.messages.get(WHEEL_SLIP_TOPIC, [])
    slip = np.array([(_stamp(m), *m.velocity) for m in slip_msgs]).reshape(-1, 7)
    remaining = [(int(s['periods']), float(s['remaining_m'])) for s in statuses
                 if s['message'] == 'moving' and 'remaining_m' in s]
    ends = [s for s in statuses if s['message'] in OUTCOME_NAMES]
    final = route[-1]
    summary = {
        'bag': str(bag),
        'outcome': ends[-1]['message'] if ends else 'none recorded',
        'reason': ends[-1].get('reason', '') if ends else '',
        'goal_x_mm': goal[0] * 1e3 if goal else None,
        'goal_y_mm': goal[1] * 1e3 if goal else None,
        'final_x_mm': final[1] * 1e3, 'final_y_mm': final[2] * 1e3,
        'deviation_mm': (math.hypot(final[1] - goal[0], final[2] - goal[1]) * 1e3
                         if goal else None),
        'periods': len(moves),
        'captures': len(captures),
        'route_from': 'captures' if seen_only else 'odom',
        'clock': 'wall' if is_wall_clock(float(route[0, 0])) else 'simulated',
        'duration_s': float(route[-1, 0] - route[0, 0]),
        'message_counts': {topic: len(raw) for topic, raw in data.raw.items()},
    }
    arrays = {'route': route, 'captures': captures, 'slip': slip,
              'move_starts': np.array([_stamp(m) for m in moves]),
              'remaining': np.array(remaining).reshape(-1, 2),
              'goal': np.array(goal if goal else route[-1, 1:])}
    return summary, arrays


def route_of(messages: dict[str, list]) -> tuple[np.ndarray, bool]:
    """The route (time, x, y) from /odom; from a run with a real robot, which has none, where
    the cameras saw it (every capture, still or in motion, by its stamp), and True."""
    odometry = messages.get(ODOM_TOPIC, [])
    if odometry:
        return np.array([(_stamp(m), m.pose.pose.position.x, m.pose.pose.position.y)
                         for m in odometry]), False
    seen = [(_stamp(m), m.pose.position.x, m.pose.position.y)
            for topic in CAPTURE_TOPICS.values() for m in messages.get(topic, [])]
    seen += [(_stamp(m), m.pose.pose.position.x, m.pose.pose.position.y)
             for topic in CAPTURE_IN_MOTION_TOPICS.values() for m in messages.get(topic, [])]
    return np.array(sorted(seen)).reshape(-1, 3), True


def summary_markdown(summary: dict) -> str:
    rows = [('outcome', f"{summary['outcome']} {summary['reason']}".strip()),
            ('goal', f"({summary['goal_x_mm']:.4f}, {summary['goal_y_mm']:.4f}) mm"
             if summary['goal_x_mm'] is not None else 'not recorded'),
            ('final position' + (' (as the cameras saw it)' if summary['route_from'] == 'captures'
                                 else ''),
             f"({summary['final_x_mm']:.4f}, {summary['final_y_mm']:.4f}) mm"),
            ('final deviation', f"{summary['deviation_mm'] * 1e3:.2f} um"
             if summary['deviation_mm'] is not None else 'unknown (no goal in the bag)'),
            ('periods', str(summary['periods'])),
            ('captures', str(summary['captures'])),
            (f"duration ({summary['clock']} clock)", f"{summary['duration_s']:.2f} s")]
    lines = [f"# Run recorded in `{summary['bag']}`", '', '| | |', '|---|---|']
    lines += [f'| {name} | {value} |' for name, value in rows]
    lines += ['', '| topic | messages |', '|---|---|']
    lines += [f'| `{topic}` | {count} |' for topic, count in summary['message_counts'].items()]
    return '\n'.join(lines) + '\n'


def run(args: argparse.Namespace) -> int:
    from omni_micro_cli import plots
    from omni_micro_tools.bag_reading import bag_topics, check_readable_bag
    from omni_micro_tools.fleet_analysis import fleet_robots

    check_readable_bag(args.bag)
    robots = fleet_robots(bag_topics(args.bag))
    if robots:
        return analyze_fleet(args, robots)
    summary, arrays = summarize(args.bag)
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
            f'{len(robots)} robots (from {args.bag.name})'))
        if args.animate:
            from omni_micro_vision.animation import animate

            animate(args.bag, scratch / f'run.{args.animate}', args.frames, args.fps,
                    scratch / 'run_last_frame.png', robots=robots)
        (scratch / 'summary.json').write_text(json.dumps(summary, indent=2))
        (scratch / 'summary.md').write_text(fleet_markdown(summary))
    print(fleet_markdown(summary))
    print(f'figures and summary in {args.out}/', file=sys.stderr)
    return 0
