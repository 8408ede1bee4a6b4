"""`analyze` of a fleet's bag (omni-micro fleet --record, or through the graph): a table per robot,
with its own timing, and what the figure of their routes draws."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from omni_micro_common.conventions import STATUS_TIME_KEY, join_stamp
from omni_micro_common.topic_names import (
    CONTROLLER_STATUS_TOPIC,
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


def summarize_fleet(bag: Path, robots: list[int]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Per robot: when it set out (its first goal's stamp), when it reached each goal (its
    controller's ``reached``, by the time of what decided it), its own duration (from setting
    out to its last goal reached), where it ended, how far from its last goal, how far it
    drove; and what the figure draws of it (route, goals, start, end). Its goals are its goal
    poses: each goal its controller was handed, every point of its legs (the last of a leg its
    task's goal), in a graph's bag and in the fleet twin's alike."""
    from omni_micro_tools.bag_reading import read_bag

    topics = [robot_topic(k, topic) for k in robots
              for topic in (ODOM_TOPIC, GOAL_TOPIC, CONTROLLER_STATUS_TOPIC)]
    data = read_bag(bag, topics=topics)
    rows, drawn = [], {}
    for k in robots:
        odometry = data.messages.get(robot_topic(k, ODOM_TOPIC), [])
        route = np.array([(join_stamp(m.header.stamp.sec, m.header.stamp.nanosec),
                           m.pose.pose.position.x, m.pose.pose.position.y)
                          for m in odometry]).reshape(-1, 3)
        goals = [(join_stamp(m.header.stamp.sec, m.header.stamp.nanosec), m.pose.position.x,
                  m.pose.position.y) for m in data.messages.get(robot_topic(k, GOAL_TOPIC), [])]
        reached = reached_times(goals, data.messages.get(robot_topic(k, CONTROLLER_STATUS_TOPIC),
                                                         []))
        final = route[-1] if len(route) else np.full(3, math.nan)
        set_out = goals[0][0] if goals else None
        done = [at for at in reached if at is not None]
        rows.append({
            'robot': robot_name(k), 'goals': len(goals), 'goals_reached': len(done),
            'set_out_s': set_out, 'reached_at_s': reached,
            'duration_s': (max(done) - set_out) if done and set_out is not None else None,
            'final_x_mm': float(final[1]) * 1e3, 'final_y_mm': float(final[2]) * 1e3,
            'last_goal_deviation_um': (math.hypot(final[1] - goals[-1][1],
                                                  final[2] - goals[-1][2]) * 1e6
                                       if goals and len(route) else None),
            'driven_mm': float(np.sum(np.hypot(*np.diff(route[:, 1:], axis=0).T))) * 1e3})
        drawn[robot_name(k)] = {'route_m': route[:, 1:],
                                'goals_m': np.array([goal[1:] for goal in goals]).reshape(-1, 2)}
    return {'bag': str(bag), 'robots': rows}, drawn


def reached_times(goals: list[tuple[float, float, float]], statuses: list[Any]
                  ) -> list[float | None]:
    """When each goal (stamp, x, y) was reached: the first ``reached`` status of the robot's
    controller at or after the goal's stamp for that goal (None: not reached)."""
    ends = []
    for status in statuses:
        values = {item.key: item.value for item in status.values}
        if status.message == 'reached' and STATUS_TIME_KEY in values:
            ends.append((float(values[STATUS_TIME_KEY]), values.get('goal_x_m'),
                         values.get('goal_y_m')))
    times: list[float | None] = []
    for stamp_s, x_m, y_m in goals:
        times.append(next((at for at, goal_x, goal_y in ends if at >= stamp_s - 1e-9
                           and (goal_x is None or abs(float(goal_x) - x_m) < 1e-9)
                           and (goal_y is None or abs(float(goal_y) - y_m) < 1e-9)), None))
    return times


def fleet_markdown(summary: dict[str, Any]) -> str:
    lines = [f"# Fleet run recorded in `{summary['bag']}`", '',
             '| robot | goal poses reached | set out (s) | each reached at (s) | duration (s) | '
             'final position (mm) | from its last goal (um) | driven (mm) |',
             '|---|---|---|---|---|---|---|---|']
    for row in summary['robots']:
        deviation = row['last_goal_deviation_um']
        reached = ', '.join(f'{at:.2f}' if at is not None else '-'
                            for at in row['reached_at_s'])
        lines.append(f"| {row['robot']} | {row['goals_reached']}/{row['goals']} | "
                     + _number(row['set_out_s']) + f' | {reached or "-"} | '
                     + _number(row['duration_s'])
                     + f" | ({row['final_x_mm']:.3f}, {row['final_y_mm']:.3f}) | "
                     + (f'{deviation:.2f}' if deviation is not None else 'no goal')
                     + f" | {row['driven_mm']:.1f} |")
    return '\n'.join(lines) + '\n'


def _number(value: float | None) -> str:
    return f'{value:.2f}' if value is not None else '-'
