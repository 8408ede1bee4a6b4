"""`omni-micro bench-graph`: how fast the node graph runs Fig. 11's closed loop, idle and busy.

Each row is one recorded run of the Fig. 11 closed loop through the three node processes; the
figure of merit is the real-time factor reached (simulated seconds per wall second, from the
clock's start to the outcome). Load comes from other programs spinning on the machine's cores,
as on a shared CI host. The lockstep rows must all end at the same pose: a busy machine may
slow a run down, never change it.
"""

from __future__ import annotations

import argparse
import math
import os
import pstats
import statistics
import tempfile
from pathlib import Path

from omni_micro_bringup.graph import GraphResult, run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.machine_load import busy_cores
from omni_micro_cli.arguments import non_negative_int
from omni_micro_cli.outputs import output_folder, print_json
from omni_micro_sim import paper

# (label, real-time factor, lockstep, cores kept busy by other programs, loop in one process)
CASES = (('lockstep --rtf max, idle', math.inf, True, 0, False),
         ('lockstep --rtf max, 1 core busy', math.inf, True, 1, False),
         ('lockstep --rtf max, 2 cores busy', math.inf, True, 2, False),
         ('free-running --rtf 20, idle', 20.0, False, 0, False),
         ('free-running --rtf 20, 1 core busy', 20.0, False, 1, False),
         ('--composed lockstep --rtf max, idle', math.inf, True, 0, True),
         ('--composed lockstep, 1 core busy', math.inf, True, 1, True),
         ('--composed lockstep, 2 cores busy', math.inf, True, 2, True))


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bench-graph',
        description='Run the Fig. 11 closed loop, recorded, through the node graph in lockstep '
                    'at --rtf max (idle, one and two cores kept busy by other programs; as '
                    'separate processes and --composed) and '
                    'free-running at --rtf 20, and print the real-time factor each reached, '
                    'its outcome and final pose. Target: >= 30x in lockstep on an idle 2-core '
                    'machine.')
    parser.add_argument('--profile', type=output_folder, metavar='DIR',
                        help='then one more idle lockstep run with each node under cProfile '
                             '(slower, so not in the table): print where its time goes and keep '
                             'the .prof files in DIR')
    parser.add_argument('--markers-pairs', type=non_negative_int, default=3, metavar='N',
                        help='then N pairs of idle runs without and with markers_node, for '
                             'what the markers cost (default 3; 0 skips it)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the rest on stderr)')
    parser.set_defaults(handler=run)


def one_run(rtf: float, lockstep: bool, busy: int, scratch: Path, name: str,
            markers: bool = True, composed: bool = False) -> GraphResult:
    with busy_cores(busy):
        return run_graph(GraphOptions(
            goal_m=paper.FIG11_GOAL_M, real_time_factor=rtf, lockstep=lockstep,
            log_dir=scratch / 'logs', record=scratch / name, timeout_s=300.0, markers=markers,
            composed=composed))


def markers_cost(pairs: int, scratch: Path) -> dict[str, float]:
    """Idle lockstep runs with and without markers_node, alternating; median rtf of each."""
    reached: dict[bool, list[float]] = {True: [], False: []}
    for pair in range(pairs):
        for markers in (False, True):
            result = one_run(math.inf, True, 0, scratch, f'markers{pair}{markers}', markers)
            reached[markers].append(result.sim_time_s / result.wall_time_s)
    without, with_markers = statistics.median(reached[False]), statistics.median(reached[True])
    print(f'markers cost ({pairs} pairs, idle lockstep --rtf max, recorded): rtf without '
          f'{without:.1f}, with {with_markers:.1f} (median): '
          f'{100 * (1 - with_markers / without):+.1f} % slower (target < 10 %)', flush=True)
    return {'rtf_without_markers': round(without, 2), 'rtf_with_markers': round(with_markers, 2),
            'slower_percent': round(100 * (1 - with_markers / without), 1)}


def profile_summary(folder: Path, top: int = 8) -> dict[str, list[tuple[str, float]]]:
    """Per node: the functions with the most own time (s), rclpy's wait excluded (idle)."""
    summary = {}
    for path in sorted(folder.glob('*.prof')):
        stats = pstats.Stats(str(path)).stats  # type: ignore[attr-defined]
        rows = sorted(((f'{Path(file).name}:{line}({function})', values[2])
                       for (file, line, function), values in stats.items()
                       if function != "<built-in method rclpy._rclpy_pybind11.wait>"),
                      key=lambda row: -row[1])
        summary[path.stem] = rows[:top]
    return summary


def run(args: argparse.Namespace) -> int:
    rows = []
    with tempfile.TemporaryDirectory(prefix='omni-micro-bench-graph-') as folder:
        scratch = Path(folder)
        for index, (label, rtf, lockstep, busy, composed) in enumerate(CASES):
            result = one_run(rtf, lockstep, busy, scratch, f'bag{index}', composed=composed)
            rtf_reached = result.sim_time_s / result.wall_time_s
            rows.append({'case': label, 'outcome': result.outcome,
                         'rtf_reached': round(rtf_reached, 1),
                         'sim_time_s': round(result.sim_time_s, 3),
                         'wall_time_s': round(result.wall_time_s, 2),
                         'periods': result.periods,
                         'final_x_mm': round(result.final_x_m * 1e3, 7),
                         'deviation_um': round(result.deviation_m * 1e6, 3)})
            print(f'{label:36s} {result.outcome:8s} rtf {rtf_reached:5.1f}  '
                  f'{result.sim_time_s:6.2f} s sim in {result.wall_time_s:5.2f} s wall, '
                  f'{result.periods} periods, {result.deviation_m * 1e6:.3f} um from the goal',
                  flush=True)
    lockstep_poses = {(row['final_x_mm'], row['sim_time_s'], row['periods'])
                      for row, case in zip(rows, CASES, strict=True) if case[2]}
    idle, composed_idle = rows[0]['rtf_reached'], rows[5]['rtf_reached']
    print(f'lockstep runs identical: {len(lockstep_poses) == 1}; idle lockstep rtf {idle}, '
          f'--composed {composed_idle} (target >= 30; >= 20 with 2 cores busy: '
          f'{rows[2]["rtf_reached"]}, --composed {rows[7]["rtf_reached"]}); free-running rtf 20 '
          f'reached {rows[3]["rtf_reached"]}')
    report: dict[str, object] = {'runs': rows, 'lockstep_identical': len(lockstep_poses) == 1}
    if args.markers_pairs:
        with tempfile.TemporaryDirectory(prefix='omni-micro-bench-graph-') as folder:
            report['markers'] = markers_cost(args.markers_pairs, Path(folder))
    if args.profile is not None:
        args.profile.mkdir(parents=True, exist_ok=True)
        os.environ['OMNI_MICRO_PROFILE'] = str(args.profile.resolve())
        try:
            with tempfile.TemporaryDirectory(prefix='omni-micro-bench-graph-') as folder:
                one_run(math.inf, True, 0, Path(folder), 'profiled')
        finally:
            os.environ.pop('OMNI_MICRO_PROFILE', None)
        summary = profile_summary(args.profile)
        for node, top in summary.items():
            print(f'profile {node} (own time, s):')
            for function, seconds in top:
                print(f'  {seconds:7.3f}  {function}')
        report['profile'] = summary
    if args.json:
        print_json(report)
    return 0
