"""`analyze` of a fleet's bag (omni-micro fleet --record): a table per robot and their routes."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from omni_micro_common.topic_names import (
    GOAL_TOPIC,
    ODOM_TOPIC,
    robot_index,
    robot_name,
    robot_topic,
)
from omni_micro_tools.topics import robot_and_topic


def fleet_robots(topics: list[str]) -> list[int]:
    """The robots a bag holds odometry of under /robot_k/ (none: not a fleet's bag)."""
    return sorted(index for robot, own in map(robot_and_topic, topics)
                  if own == ODOM_TOPIC and (index := robot_index(robot)) is not None)


def summarize_fleet(bag: Path, robots: list[int]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """Per robot: its goals, where it ended, how far from its last goal, how far it drove."""
    from omni_micro_tools.bag_reading import read_bag

    topics = [robot_topic(k, topic) for k in robots for topic in (ODOM_TOPIC, GOAL_TOPIC)]
    data = read_bag(bag, topics=topics)
    rows, routes = [], {}
    for k in robots:
        odometry = data.messages.get(robot_topic(k, ODOM_TOPIC), [])
        route = np.array([(m.header.stamp.sec + m.header.stamp.nanosec * 1e-9,
                           m.pose.pose.position.x, m.pose.pose.position.y)
                          for m in odometry]).reshape(-1, 3)
        goals = [(m.pose.position.x, m.pose.position.y)
                 for m in data.messages.get(robot_topic(k, GOAL_TOPIC), [])]
        final = route[-1] if len(route) else np.full(3, math.nan)
        rows.append({
            'robot': robot_name(k), 'goals': len(goals),
            'final_x_mm': float(final[1]) * 1e3, 'final_y_mm': float(final[2]) * 1e3,
            'last_goal_deviation_um': (math.hypot(final[1] - goals[-1][0],
                                                  final[2] - goals[-1][1]) * 1e6
                                       if goals and len(route) else None),
            'driven_mm': float(np.sum(np.hypot(*np.diff(route[:, 1:], axis=0).T))) * 1e3,
            'duration_s': float(route[-1, 0] - route[0, 0]) if len(route) else 0.0})
        routes[robot_name(k)] = route[:, 1:]
    return {'bag': str(bag), 'robots': rows}, routes


def fleet_markdown(summary: dict[str, Any]) -> str:
    lines = [f"# Fleet run recorded in `{summary['bag']}`", '',
             '| robot | goals | final position (mm) | from its last goal (um) | driven (mm) | '
             'duration (s) |', '|---|---|---|---|---|---|']
    for row in summary['robots']:
        deviation = row['last_goal_deviation_um']
        lines.append(f"| {row['robot']} | {row['goals']} | ({row['final_x_mm']:.3f}, "
                     f"{row['final_y_mm']:.3f}) | "
                     + (f'{deviation:.2f}' if deviation is not None else 'no goal')
                     + f" | {row['driven_mm']:.1f} | {row['duration_s']:.2f} |")
    return '\n'.join(lines) + '\n'
