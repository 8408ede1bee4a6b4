"""The fleet measured in its twin (``omni-micro fleet-study``): throughput against the number of
robots, and robots crossing each other's goals, seed after seed."""

from __future__ import annotations

import io
import math
import random
import time
from typing import Any

from omni_micro_control.fleet_files import OPEN_LOOP

# The crossing: robots on a circle, each sent to the opposite point, so that every path crosses
# the middle (four robots make a cross of the platform, 100 mm end to end; sixteen stand 19.5 mm
# apart around it).
CROSSING_CENTRE_M = (0.05, 0.0)
CROSSING_RADIUS_M = 0.05
CROSSING_ROBOTS = range(2, 25, 2)   # even counts whose neighbours stand 12 mm apart or more
# How the figure names each controller mode.
CONTROLLER_NAMES = {'paper': "on the paper's rule", 'model': 'in the model mode',
                    'servo': 'in the servo mode', OPEN_LOOP: 'driven open loop'}
COLUMNS = ('robots', 'controller', 'seed', 'outcome', 'goals', 'sim_time_s', 'goals_per_minute',
           'closest_gap_mm', 'farthest_off_leg_mm', 'wall_s')


def crossing_places(robots: int) -> tuple[list[tuple[float, float]], list[tuple[float, float]]]:
    """The crossing's starts and goals: opposite pairs of the circle, the first pair from its
    west to its east end, each next pair turned 360 / ``robots`` degrees clockwise."""
    if robots not in CROSSING_ROBOTS:
        raise ValueError(f'a crossing of {robots} robots: expected an even count from '
                         f'{CROSSING_ROBOTS.start} to {CROSSING_ROBOTS.stop - 1}')
    starts, goals = [], []
    for pair in range(robots // 2):
        angle = math.pi - 2.0 * math.pi * pair / robots
        for start, goal in ((angle, angle + math.pi), (angle + math.pi, angle)):
            # Rounded to the nanometre (a cosine of 90 degrees is 6e-17, not 0).
            starts.append(_on_circle(start))
            goals.append(_on_circle(goal))
    return starts, goals


def _on_circle(angle_rad: float) -> tuple[float, float]:
    x, y = (centre + CROSSING_RADIUS_M * f(angle_rad)
            for centre, f in zip(CROSSING_CENTRE_M, (math.cos, math.sin), strict=True))
    return round(x, 9) + 0.0, round(y, 9) + 0.0   # + 0.0: never -0.0


def one_run(robots: int, seed: int, goals_per_robot: int, crossing: bool,
            controller: str = 'paper') -> dict[str, Any]:
    """One fleet twin run: its row (``crossing``: ``robots`` of the crossing, one goal each)."""
    from omni_micro_control.fleet_files import drawn_offsets, fleet_from, robot_parameters
    from omni_micro_control.fleet_plan import Task, plan_fleet
    from omni_micro_studies.fleet_twin import run_fleet

    started = time.perf_counter()
    if crossing:
        rng = random.Random(f'robots {seed}')
        starts, goals = crossing_places(robots)
        tasks = [[Task(goal)] for goal in goals]
        parameters = [robot_parameters(drawn_offsets(rng)) for _ in starts]
    else:
        fleet = fleet_from(str(robots), None, goals_per_robot, seed)
        starts, tasks, parameters = fleet.starts_m, fleet.tasks, fleet.robots
    plan = plan_fleet(starts, tasks, seed=seed)
    result = run_fleet(plan, robots=parameters, seed=seed, controllers=[controller] * len(starts))
    return {'robots': robots, 'controller': controller, 'seed': seed, 'outcome': result.outcome,
            'goals': result.tasks_done, 'sim_time_s': round(result.sim_time_s, 3),
            'goals_per_minute': round(result.goals_per_minute, 4),
            # One robot alone has no closest other: None (JSON's null, an empty CSV cell).
            'closest_gap_mm': round(result.closest_gap_m * 1e3, 4)
            if math.isfinite(result.closest_gap_m) else None,
            'farthest_off_leg_mm': round(max(r.off_leg_m for r in result.robots) * 1e3, 4),
            'wall_s': round(time.perf_counter() - started, 2)}


def crossing_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    return {'runs': len(rows), 'robots': rows[0]['robots'],
            'done': sum(r['outcome'] == 'done' for r in rows),
            'contacts': sum(r['outcome'] == 'contact' for r in rows),
            'closest_gap_mm': min(r['closest_gap_mm'] for r in rows),
            'farthest_off_leg_mm': max(r['farthest_off_leg_mm'] for r in rows),
            'sim_time_s_mean': sum(r['sim_time_s'] for r in rows) / len(rows)}


def throughput_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    counts = sorted({r['robots'] for r in rows})
    per_count = []
    for n in counts:
        mine = [r for r in rows if r['robots'] == n]
        rates = [r['goals_per_minute'] for r in mine]
        per_count.append({'robots': n, 'runs': len(mine),
                          'done': sum(r['outcome'] == 'done' for r in mine),
                          'goals_per_minute_mean': sum(rates) / len(rates),
                          'goals_per_minute_min': min(rates), 'goals_per_minute_max': max(rates),
                          'closest_gap_mm': min((r['closest_gap_mm'] for r in mine
                                                 if r['closest_gap_mm'] is not None),
                                                default=None)})
    return {'per_robot_count': per_count, 'runs': len(rows),
            'contacts': sum(r['outcome'] == 'contact' for r in rows),
            'farthest_off_leg_mm': max(r['farthest_off_leg_mm'] for r in rows)}


def summary_lines(summary: dict[str, Any], crossing: bool) -> list[str]:
    if crossing:
        return [f'{summary["runs"]} crossing runs of {summary["robots"]} robots '
                f'({summary["controller"]} controllers): {summary["done"]} done, '
                f'{summary["contacts"]} contacts; closest centres {summary["closest_gap_mm"]:.2f}'
                f' mm (9 mm discs); farthest off a leg {summary["farthest_off_leg_mm"]:.3f} mm; '
                f'{summary["sim_time_s_mean"]:.1f} s simulated on average']
    lines = [f'{"robots":>6} {"runs":>5} {"done":>5} {"goals/min":>10} {"min..max":>13} '
             f'{"closest mm":>10}']
    for entry in summary['per_robot_count']:
        lines.append(f'{entry["robots"]:>6} {entry["runs"]:>5} {entry["done"]:>5} '
                     f'{entry["goals_per_minute_mean"]:>10.2f} '
                     f'{entry["goals_per_minute_min"]:>6.2f}..{entry["goals_per_minute_max"]:<6.2f}'
                     + (f' {entry["closest_gap_mm"]:>10.2f}' if entry['closest_gap_mm']
                        is not None else f' {"-":>10}'))
    lines.append(f'{summary["contacts"]} contacts in {summary["runs"]} runs '
                 f'({summary["controller"]} controllers); farthest off a leg '
                 f'{summary["farthest_off_leg_mm"]:.3f} mm')
    return lines


def throughput_figure(summaries: list[dict[str, Any]]) -> bytes:
    """Goals per simulated minute against N: a line per controller's summary, each point the
    mean over its task sets and its bar their min..max."""
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib import pyplot as plt

    figure, axes = plt.subplots(figsize=(6, 4))
    for index, summary in enumerate(summaries):
        entries = summary['per_robot_count']
        # Side by side when several: the bars of one robot count would hide each other.
        shift = (index - (len(summaries) - 1) / 2) * 0.25 if len(summaries) > 1 else 0.0
        counts = [e['robots'] + shift for e in entries]
        means = [e['goals_per_minute_mean'] for e in entries]
        axes.errorbar(counts, means, yerr=[[m - e['goals_per_minute_min'] for m, e in
                                            zip(means, entries, strict=True)],
                                           [e['goals_per_minute_max'] - m for m, e in
                                            zip(means, entries, strict=True)]],
                      marker='o', capsize=3, label=CONTROLLER_NAMES[summary['controller']])
    axes.set_xlabel('robots on the platform')
    axes.set_ylabel('goals reached per simulated minute')
    if len(summaries) == 1:
        mode = CONTROLLER_NAMES[summaries[0]['controller']]
        axes.set_title(f'Fleet throughput, every robot {mode}\n(min..max over task sets)')
    else:
        draws = max(e['runs'] for summary in summaries for e in summary['per_robot_count'])
        axes.set_title(f'Fleet throughput, every robot on one controller\n(mean and min..max '
                       f'over {draws} task sets, the same for each)')
        axes.legend(title='every robot', fontsize='small')
    axes.set_ylim(bottom=0.0)
    axes.grid(alpha=0.3)
    buffer = io.BytesIO()
    figure.tight_layout()
    figure.savefig(buffer, format='png', dpi=110)
    plt.close(figure)
    return buffer.getvalue()
