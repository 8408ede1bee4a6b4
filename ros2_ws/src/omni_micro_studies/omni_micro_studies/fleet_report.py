"""What ``omni-micro fleet`` reports of a fleet's run, in the twin or through the graph (told as
the twin tells its own, :mod:`fleet_routes`): its summary (the JSON, per robot and for the
whole), the table of it, and the figure of every robot's route."""

from __future__ import annotations

import math
from typing import Any

from omni_micro_common.topic_names import robot_name
from omni_micro_control.fleet_files import Fleet
from omni_micro_control.fleet_roadmap import CLEARANCE_M


def summarize(fleet: Fleet, plan: Any, result: Any, planned_s: float, wall_s: float,
              running_wall_s: float | None = None) -> dict[str, Any]:
    from omni_micro_vision.camera import DEFAULT_RIG

    robots = []
    for k, run in enumerate(result.robots):
        final = run.final_state
        goals = []
        for index, task in enumerate(fleet.tasks[k]):
            seen = DEFAULT_RIG.resolution_at(*task.goal_m)
            reached = index < len(run.tasks_done_s)
            goals.append({
                'goal_mm': [v * 1e3 for v in task.goal_m],
                'camera': seen[0] if seen else None,
                'reached_at_s': run.tasks_done_s[index] if reached else None,
                'deviation_um': run.deviations_m[index] * 1e6 if reached else None,
                # The 95 % radius of the captures that told it reached: its own error.
                'capture_95_um': seen[1] * 1e6 if seen else None})
        robots.append({
            'robot': robot_name(k), 'start_mm': [v * 1e3 for v in fleet.starts_m[k]],
            'wheel_offsets_deg': list(fleet.offsets_deg[k]), 'controller': fleet.controllers[k],
            'goals': len(fleet.tasks[k]), 'goals_reached': len(run.tasks_done_s),
            'reached_at_s': run.tasks_done_s,
            'deviation_um': [d * 1e6 for d in run.deviations_m],
            'goal_results': goals,
            'legs': len(plan.legs[k]), 'moves': run.moves,
            'farthest_off_leg_mm': run.off_leg_m * 1e3,
            'final_mm': [final.x_m * 1e3, final.y_m * 1e3],
            'final_phi_deg': math.degrees(final.phi_rad), 'outcome': run.outcome or 'done',
            'learnt_offsets_deg': ([math.degrees(v) for v in run.learnt_offsets_rad]
                                   if run.learnt_offsets_rad is not None else None)})
    return {'outcome': result.outcome, 'reason': result.reason, 'robots': robots,
            'sim_time_s': result.sim_time_s, 'goals_reached': result.tasks_done,
            'goals_per_minute': result.goals_per_minute,
            'closest_gap_mm': (result.closest_gap_m * 1e3
                               if math.isfinite(result.closest_gap_m) else None),
            'closest_pair': list(result.closest_pair) if result.closest_pair else None,
            'planning_s': planned_s, 'wall_s': wall_s, 'running_wall_s': running_wall_s}


def worst_by_camera(robot: dict[str, Any], camera: str) -> str:
    """The robot's worst true distance from a goal ``camera`` sees, with that camera's
    captures' own error (95 %) beside it: ``12.13+-26.39``; ``-`` for none reached."""
    seen = [goal for goal in robot['goal_results']
            if goal['camera'] == camera and goal['deviation_um'] is not None]
    if not seen:
        return '-'
    worst = max(seen, key=lambda goal: goal['deviation_um'])
    return f"{worst['deviation_um']:.2f}+-{worst['capture_95_um']:.2f}"


def fleet_table(summary: dict[str, Any]) -> list[str]:
    """The table ``fleet`` prints: a row per robot, then the whole run's line."""
    lines = [f'{"robot":<8} {"control":<7} {"goals":>7} {"last at s":>9} {"micro um":>12} '
             f'{"macro um":>12} {"legs":>5} {"moves":>6} {"off leg mm":>10} '
             f'{"learnt xi2,xi3 deg":>18}  outcome']
    for robot in summary['robots']:
        last = max(robot['reached_at_s'], default=float('nan'))
        learnt = robot['learnt_offsets_deg']
        learnt_text = f'{learnt[0]:.3f}, {learnt[1]:.3f}' if learnt is not None else '-'
        lines.append(f'{robot["robot"]:<8} {robot["controller"]:<7} '
                     f'{robot["goals_reached"]:>3}/{robot["goals"]:<3} '
                     f'{last:>9.2f} {worst_by_camera(robot, "micro"):>12} '
                     f'{worst_by_camera(robot, "macro"):>12} {robot["legs"]:>5} '
                     f'{robot["moves"]:>6} {robot["farthest_off_leg_mm"]:>10.3f} '
                     f'{learnt_text:>18}  {robot["outcome"]}')
    gap = summary['closest_gap_mm']
    pair = summary['closest_pair']
    lines.append(f'{summary["outcome"]}: {summary["reason"]}; {summary["goals_reached"]} goals, '
                 f'{summary["goals_per_minute"]:.2f} per simulated minute; closest centres '
                 + (f'{gap:.2f} mm (robots {pair[0]} and {pair[1]}; planned '
                    f'{CLEARANCE_M * 1e3:g} mm or more)' if gap is not None else 'n/a')
                 + f'; planned in {summary["planning_s"]:.2f} s, {summary["wall_s"]:.1f} s of '
                   'wall time in all')
    return lines


def route_figure(plan: Any, result: Any) -> bytes:
    """Every robot's route, start, goals and end, and the micro field
    (:mod:`omni_micro_vision.fleet_figure`)."""
    import numpy as np

    from omni_micro_vision.fleet_figure import DrawnRobot, fleet_routes_png

    drawn = [DrawnRobot(k, robot_name(k), run.route_m[:, 1:3] if len(run.route_m) else
                        np.zeros((0, 2)), np.array([task.goal_m for task in plan.tasks[k]]),
                        len(run.tasks_done_s), plan.starts_m[k])
             for k, run in enumerate(result.robots)]
    return fleet_routes_png(drawn, f'{len(result.robots)} robots: {result.outcome}, '
                                   f'{result.sim_time_s:.1f} s simulated')
