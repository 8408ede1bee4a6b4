"""`omni-micro fleet-study`: the micro-factory measured: throughput against the number of
robots, and robots crossing each other's goals, seed after seed."""

from __future__ import annotations

import argparse
import csv
import io
import json
import random
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from omni_micro_cli.arguments import positive_int, seed_number, whole_number_in
from omni_micro_cli.outputs import echo_to_stderr, output_folder, staged_directory
from omni_micro_control.feedback import MODES

# Four robots on a cross, each sent to the opposite end: every path crosses every other's goal.
CROSSING_STARTS_M = [(0.0, 0.0), (0.1, 0.0), (0.05, 0.05), (0.05, -0.05)]
CROSSING_GOALS_M = [(0.1, 0.0), (0.0, 0.0), (0.05, -0.05), (0.05, 0.05)]
# How the figure names each controller mode.
CONTROLLER_NAMES = {'paper': "on the paper's rule", 'model': 'in the model mode',
                    'servo': 'in the servo mode'}
COLUMNS = ('robots', 'controller', 'seed', 'outcome', 'goals', 'sim_time_s', 'goals_per_minute',
           'closest_gap_mm', 'farthest_off_leg_mm', 'wall_s')


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'fleet-study',
        description='Measure the micro-factory in the fleet twin. Throughput: 1..--robots-max '
                    'robots, --draws task sets each (each robot to the micro field, then to '
                    'a place of its own, --goals-per-robot goals), goals reached per simulated '
                    'minute against N, with the figure. --crossing RUNS instead: RUNS seeded '
                    'runs of 4 robots sent across the platform through each other\'s goals, '
                    'wheel offsets drawn per seed; contacts counted. Writes runs.csv, '
                    'summary.json and throughput.png (crossing: the first two) into --out, all '
                    'or nothing.')
    parser.add_argument('--out', type=output_folder, required=True, metavar='DIR',
                        help='folder for the results (created if need be; files of the same '
                             'names in it are replaced)')
    parser.add_argument('--robots-max', type=whole_number_in(1, 16), default=8, metavar='N',
                        help='sweep 1..N robots (default 8)')
    parser.add_argument('--draws', type=whole_number_in(1, 1000), default=3, metavar='K',
                        help='task sets per robot count (default 3)')
    parser.add_argument('--goals-per-robot', type=whole_number_in(1, 20), default=2,
                        metavar='K', help='goals per robot (default 2)')
    parser.add_argument('--crossing', type=whole_number_in(1, 100000), metavar='RUNS',
                        help='instead of the sweep: RUNS crossing runs of 4 robots')
    parser.add_argument('--controller', choices=MODES, default='paper',
                        help="every robot's controller: paper (section 4.1's rule, the "
                             'default), model or servo (docs/control.md)')
    parser.add_argument('--seed', type=seed_number, default=0, help='first seed (default 0)')
    parser.add_argument('--workers', type=positive_int, default=2,
                        help='processes running the runs side by side (default 2)')
    parser.set_defaults(handler=run)


def one_run(robots: int, seed: int, goals_per_robot: int, crossing: bool,
            controller: str = 'paper') -> dict[str, Any]:
    """One fleet twin run: its row."""
    from omni_micro_control.fleet_files import drawn_offsets, fleet_from, robot_parameters
    from omni_micro_control.fleet_plan import Task, plan_fleet
    from omni_micro_studies.fleet_twin import run_fleet

    started = time.perf_counter()
    if crossing:
        rng = random.Random(f'robots {seed}')
        starts = CROSSING_STARTS_M
        tasks = [[Task(goal)] for goal in CROSSING_GOALS_M]
        parameters = [robot_parameters(drawn_offsets(rng)) for _ in starts]
    else:
        fleet = fleet_from(str(robots), None, goals_per_robot, seed)
        starts, tasks, parameters = fleet.starts_m, fleet.tasks, fleet.robots
    plan = plan_fleet(starts, tasks, seed=seed)
    result = run_fleet(plan, robots=parameters, seed=seed, controllers=[controller] * len(starts))
    return {'robots': robots, 'controller': controller, 'seed': seed, 'outcome': result.outcome,
            'goals': result.tasks_done, 'sim_time_s': round(result.sim_time_s, 3),
            'goals_per_minute': round(result.goals_per_minute, 4),
            'closest_gap_mm': round(result.closest_gap_m * 1e3, 4),
            'farthest_off_leg_mm': round(max(r.off_leg_m for r in result.robots) * 1e3, 4),
            'wall_s': round(time.perf_counter() - started, 2)}


def run(args: argparse.Namespace) -> int:
    crossing = args.crossing is not None
    jobs = ([(4, args.seed + k) for k in range(args.crossing)] if crossing else
            [(n, args.seed + k) for n in range(1, args.robots_max + 1) for k in range(args.draws)])
    echo_to_stderr(f'{len(jobs)} fleet runs on {args.workers} processes')
    rows: list[dict[str, Any]] = []
    started = time.perf_counter()
    with ProcessPoolExecutor(max_workers=args.workers) as pool:
        futures = [pool.submit(one_run, n, seed, args.goals_per_robot, crossing, args.controller)
                   for n, seed in jobs]
        try:
            for future in futures:
                rows.append(future.result())
                row = rows[-1]
                echo_to_stderr(f'  [{len(rows)}/{len(jobs)}] {row["robots"]} robots, seed '
                               f'{row["seed"]}: {row["outcome"]}, {row["goals"]} goals in '
                               f'{row["sim_time_s"]:.0f} s, closest {row["closest_gap_mm"]:.2f}'
                               f' mm ({time.perf_counter() - started:.0f} s)')
        except BaseException:
            for future in futures:
                future.cancel()
            raise
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=COLUMNS)
    writer.writeheader()
    writer.writerows(rows)
    summary = {'controller': args.controller,
               **(crossing_summary(rows) if crossing else throughput_summary(rows))}
    with staged_directory(Path(args.out)) as out:
        (out / 'runs.csv').write_text(table.getvalue())
        (out / 'summary.json').write_text(json.dumps(summary, indent=1))
        if not crossing:
            (out / 'throughput.png').write_bytes(throughput_figure(summary))
    for line in summary_lines(summary, crossing):
        print(line)
    return 0 if summary['contacts'] == 0 else 1


def crossing_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    return {'runs': len(rows), 'done': sum(r['outcome'] == 'done' for r in rows),
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
                          'closest_gap_mm': min(r['closest_gap_mm'] for r in mine)})
    return {'per_robot_count': per_count, 'runs': len(rows),
            'contacts': sum(r['outcome'] == 'contact' for r in rows),
            'farthest_off_leg_mm': max(r['farthest_off_leg_mm'] for r in rows)}


def summary_lines(summary: dict[str, Any], crossing: bool) -> list[str]:
    if crossing:
        return [f'{summary["runs"]} crossing runs of 4 robots ({summary["controller"]} '
                f'controllers): {summary["done"]} done, '
                f'{summary["contacts"]} contacts; closest centres {summary["closest_gap_mm"]:.2f}'
                f' mm (9 mm discs); farthest off a leg {summary["farthest_off_leg_mm"]:.3f} mm; '
                f'{summary["sim_time_s_mean"]:.1f} s simulated on average']
    lines = [f'{"robots":>6} {"runs":>5} {"done":>5} {"goals/min":>10} {"min..max":>13} '
             f'{"closest mm":>10}']
    for entry in summary['per_robot_count']:
        lines.append(f'{entry["robots"]:>6} {entry["runs"]:>5} {entry["done"]:>5} '
                     f'{entry["goals_per_minute_mean"]:>10.2f} '
                     f'{entry["goals_per_minute_min"]:>6.2f}..{entry["goals_per_minute_max"]:<6.2f}'
                     f' {entry["closest_gap_mm"]:>10.2f}')
    lines.append(f'{summary["contacts"]} contacts in {summary["runs"]} runs '
                 f'({summary["controller"]} controllers); farthest off a leg '
                 f'{summary["farthest_off_leg_mm"]:.3f} mm')
    return lines


def throughput_figure(summary: dict[str, Any]) -> bytes:
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib import pyplot as plt

    entries = summary['per_robot_count']
    counts = [e['robots'] for e in entries]
    means = [e['goals_per_minute_mean'] for e in entries]
    figure, axes = plt.subplots(figsize=(6, 4))
    axes.errorbar(counts, means, yerr=[[m - e['goals_per_minute_min'] for m, e in
                                        zip(means, entries, strict=True)],
                                       [e['goals_per_minute_max'] - m for m, e in
                                        zip(means, entries, strict=True)]],
                  marker='o', capsize=3)
    axes.set_xlabel('robots on the platform')
    axes.set_ylabel('goals reached per simulated minute')
    mode = CONTROLLER_NAMES[summary['controller']]
    axes.set_title(f'Micro-factory throughput, every robot {mode}\n(min..max over task sets)')
    axes.set_ylim(bottom=0.0)
    axes.grid(alpha=0.3)
    buffer = io.BytesIO()
    figure.tight_layout()
    figure.savefig(buffer, format='png', dpi=110)
    plt.close(figure)
    return buffer.getvalue()

