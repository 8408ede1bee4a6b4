"""`analyze` of one robot's bag (omni-micro run --record, or simulate's): the run's numbers,
the arrays its figures draw, and its summary as markdown."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from omni_micro_common.clocks import is_wall_clock
from omni_micro_common.conventions import join_stamp
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
from omni_micro_tools.errors import BagPathError


def _stamp(msg) -> float:
    return join_stamp(msg.header.stamp.sec, msg.header.stamp.nanosec)


def summarize_run(bag: Path) -> tuple[dict, dict[str, np.ndarray]]:
    """The run's numbers and the arrays the figures need; of a run with a real robot (no
    /odom), the route where the cameras saw it (``route_from``: ``captures``)."""
    from omni_micro_tools.bag_reading import read_bag

    data = read_bag(bag)
    route, seen_only = route_of(data.messages)
    if not len(route):
        raise BagPathError(f'{str(bag)!r} has no /odom and no captures: nothing to analyse')
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
