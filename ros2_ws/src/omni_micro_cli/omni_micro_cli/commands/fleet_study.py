"""`omni-micro fleet-study`: the fleet measured in its twin: throughput against the number of
robots, and robots crossing each other's goals (omni_micro_studies.fleet_throughput)."""

from __future__ import annotations

import argparse
import csv
import io
import json
import time
from pathlib import Path
from typing import Any

from omni_micro_cli.arguments import (
    add_dask_arguments,
    check_dask_arguments,
    each_once,
    seed_number,
    whole_number_in,
    whole_numbers_in,
)
from omni_micro_cli.outputs import echo_to_stderr, output_folder, staged_directory
from omni_micro_control.fleet_files import MAX_ROBOTS, ROBOT_CONTROLLERS
from omni_micro_studies import fleet_throughput as throughput


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'fleet-study',
        description='Measure the fleet in the fleet twin. Throughput: 1..--robots-max '
                    'robots (or the --robot-counts given), --draws task sets each (each robot '
                    'to the micro field, then to a place of its own, --goals-per-robot goals), '
                    'goals reached per simulated minute against N, with the figure. --crossing '
                    'RUNS instead: RUNS seeded runs of --crossing-robots robots on a circle, '
                    'each sent to the opposite point through the others\' paths, wheel '
                    'offsets drawn per seed; contacts counted. Writes runs.csv, summary.json '
                    'and throughput.png (crossing: the first two) into --out, all or nothing.')
    parser.add_argument('--out', type=output_folder, required=True, metavar='DIR',
                        help='folder for the results (created if need be; files of the same '
                             'names in it are replaced)')
    counts = parser.add_mutually_exclusive_group()
    counts.add_argument('--robots-max', type=whole_number_in(1, MAX_ROBOTS), default=8,
                        metavar='N', help='sweep 1..N robots (default 8)')
    counts.add_argument('--robot-counts', type=whole_numbers_in(1, MAX_ROBOTS),
                        metavar='N,N,...', help='these robot counts only, e.g. 10,16,24,32,42')
    parser.add_argument('--draws', type=whole_number_in(1, 1000), default=3, metavar='K',
                        help='task sets per robot count (default 3)')
    parser.add_argument('--goals-per-robot', type=whole_number_in(1, 20), default=2,
                        metavar='K', help='goals per robot (default 2)')
    parser.add_argument('--crossing', type=whole_number_in(1, 100000), metavar='RUNS',
                        help='instead of the sweep: RUNS crossing runs')
    parser.add_argument('--crossing-robots', type=crossing_count, default=4, metavar='N',
                        help='robots in each crossing run: an even count from '
                             f'{throughput.CROSSING_ROBOTS.start} to '
                             f'{throughput.CROSSING_ROBOTS.stop - 1} (default 4)')
    parser.add_argument('--controller', type=each_once(controller_mode, 'controller'),
                        default=('paper',),
                        metavar='MODE[,MODE...]',
                        help="every robot's controller: paper (section 4.1's rule, the "
                             'default), model, servo (docs/control.md) or open-loop '
                             '(docs/fleet.md); several, e.g. '
                             'paper,model,servo: the same task sets for each, a line each in '
                             'the figure and a summary each')
    parser.add_argument('--seed', type=seed_number, default=0, help='first seed (default 0)')
    add_dask_arguments(parser)
    parser.set_defaults(handler=run)


def crossing_count(text: str) -> int:
    count = whole_number_in(throughput.CROSSING_ROBOTS.start,
                            throughput.CROSSING_ROBOTS.stop - 1)(text)
    if count % 2:
        raise argparse.ArgumentTypeError(f'expected an even count (robots in opposite pairs), '
                                         f'got {text!r}')
    return count


def controller_mode(text: str) -> str:
    if text not in ROBOT_CONTROLLERS:
        raise argparse.ArgumentTypeError(f'expected controller modes among '
                                         f'{", ".join(ROBOT_CONTROLLERS)}, '
                                         f'got {text!r}')
    return text


def run(args: argparse.Namespace) -> int:
    from omni_micro_studies.execute import map_on_dask, runs_go_to

    check_dask_arguments(args)
    crossing = args.crossing is not None
    counts = args.robot_counts or range(1, args.robots_max + 1)
    sets = ([(args.crossing_robots, args.seed + k) for k in range(args.crossing)] if crossing
            else [(n, args.seed + k) for n in counts for k in range(args.draws)])
    jobs = [(n, seed, mode) for mode in args.controller for n, seed in sets]
    echo_to_stderr(f'{len(jobs)} fleet runs on {runs_go_to(args.workers, args.scheduler)}')
    started = time.perf_counter()

    def progress(done: int, row: dict[str, Any]) -> None:
        closest = row['closest_gap_mm']
        echo_to_stderr(f'  [{done}/{len(jobs)}] {row["robots"]} robots, {row["controller"]}, seed '
                       f'{row["seed"]}: {row["outcome"]}, {row["goals"]} goals in '
                       f'{row["sim_time_s"]:.0f} s'
                       + (f', closest {closest:.2f} mm' if closest is not None else '')
                       + f' ({time.perf_counter() - started:.0f} s)')

    rows: list[dict[str, Any]] = map_on_dask(
        throughput.one_run,
        [(n, seed, args.goals_per_robot, crossing, mode) for n, seed, mode in jobs],
        workers=args.workers, scheduler=args.scheduler,
        scheduler_timeout_s=args.scheduler_timeout, on_result=progress)
    table = io.StringIO()
    writer = csv.DictWriter(table, fieldnames=throughput.COLUMNS)
    writer.writeheader()
    writer.writerows(rows)
    summaries = [{'controller': mode,
                  **(throughput.crossing_summary if crossing else throughput.throughput_summary)(
                      [row for row in rows if row['controller'] == mode])}
                 for mode in args.controller]
    # One controller: its summary alone, as it has always been written; several: each's.
    written = summaries[0] if len(summaries) == 1 else {
        'controllers': summaries, 'contacts': sum(s['contacts'] for s in summaries)}
    with staged_directory(Path(args.out)) as out:
        (out / 'runs.csv').write_text(table.getvalue())
        (out / 'summary.json').write_text(json.dumps(written, indent=1))
        if not crossing:
            (out / 'throughput.png').write_bytes(throughput.throughput_figure(summaries))
    for summary in summaries:
        if len(summaries) > 1:
            print(f'every robot {throughput.CONTROLLER_NAMES[summary["controller"]]}:')
        for line in throughput.summary_lines(summary, crossing):
            print(line)
    return 0 if all(summary['contacts'] == 0 for summary in summaries) else 1
