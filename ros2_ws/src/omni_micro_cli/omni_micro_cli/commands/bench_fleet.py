"""`omni-micro bench-fleet`: how fast the node graph runs a fleet, against its size.

Each row is one run of drawn tasks (``fleet --graph --robots N --seed S --goals-per-robot 1``)
at ``--rtf max``, stopped after ``--sim-seconds`` of simulated time (or when every task is
done, if sooner). The figure of merit is simulated robot-seconds per wall second (the robots
times the real-time factor reached, from the clock's start to the stop), and its ratio against
one robot's in the same layout and the same run of this command: what each robot added costs.
Three layouts: separate processes (dynamics_node, and each robot's vision_node and
controller_node), composed in one container, and composed as the graph chooses (one container
per core: dynamics_node in the first, the robots' nodes in the others).
"""

from __future__ import annotations

import argparse
import math
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from omni_micro_cli.arguments import positive_int, seed_number, whole_numbers_in
from omni_micro_cli.outputs import print_json
from omni_micro_control.fleet_files import MAX_ROBOTS

if TYPE_CHECKING:
    from omni_micro_bringup.graph_result import GraphResult

# (label, composed, containers: None lets the graph choose)
LAYOUTS = (('separate processes', False, None),
           ('composed, one container', True, 1),
           ('composed, one per core', True, None))
# The targets (docs/fleet.md, "The graph at scale"): (robots, layout, least rtf).
TARGETS = ((16, 'composed, one per core', 2.0), (16, 'separate processes', 1.0),
           (42, 'composed, one per core', 0.5))
# A run that has not reached its simulated seconds after this long is stopped (wall time).
RUN_TIMEOUT_S = 900.0


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bench-fleet',
        description='Run a fleet\'s drawn tasks through the node graph at --rtf max for '
                    'each robot count, in separate processes and composed (one container; one '
                    'per core), and print the simulated robot-seconds per wall second each '
                    'reached, against one robot\'s. Targets on an idle 2-core machine: 16 '
                    'robots at 2x real time composed and 1x in separate processes, 42 robots '
                    'composed at 0.5x.')
    parser.add_argument('--robot-counts', type=whole_numbers_in(1, MAX_ROBOTS),
                        default=(1, 2, 4, 8, 16, 42), metavar='N,N,...',
                        help='fleet sizes to run (default 1,2,4,8,16,42; 1 is the reference)')
    parser.add_argument('--sim-seconds', type=positive_int, default=30, metavar='S',
                        help='simulated seconds each run goes to (default 30)')
    parser.add_argument('--separate-up-to', type=positive_int, default=16, metavar='N',
                        help='larger fleets are run composed only (default 16: 42 robots are '
                             '85 processes, which two cores only take turns at)')
    parser.add_argument('--seed', type=seed_number, default=1,
                        help='the draw of starts, offsets and goals (default 1)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the rest on stderr)')
    parser.set_defaults(handler=run)


def one_run(count: int, composed: bool, containers: int | None, seed: int, sim_s: float,
            scratch: Path) -> GraphResult:
    from omni_micro_bringup.graph import run_graph
    from omni_micro_bringup.graph_options import FleetRun, GraphOptions
    from omni_micro_cli.fleet_runs import planned
    from omni_micro_control.fleet_files import fleet_from

    fleet = fleet_from(str(count), None, 1, seed)
    plan = planned(fleet, seed)
    return run_graph(GraphOptions(
        seed=seed, real_time_factor=math.inf, log_dir=scratch / 'logs', timeout_s=RUN_TIMEOUT_S,
        markers=False, composed=composed, containers=containers,
        fleet=FleetRun(plan, fleet.robots, fleet.controllers, sim_s)))


def run(args: argparse.Namespace) -> int:
    import sys

    out = sys.stderr if args.json else sys.stdout
    rows: list[dict[str, object]] = []
    one_robot: dict[str, float] = {}
    counts = sorted(set(args.robot_counts) | {1})
    with tempfile.TemporaryDirectory(prefix='omni-micro-bench-fleet-') as folder:
        for count in counts:
            for label, composed, containers in LAYOUTS:
                if not composed and count > args.separate_up_to:
                    continue
                result = one_run(count, composed, containers, args.seed,
                                 float(args.sim_seconds), Path(folder))
                rtf = result.sim_time_s / result.wall_time_s
                robot_seconds = count * rtf
                one_robot.setdefault(label, robot_seconds)
                against_one = robot_seconds / one_robot[label]
                rows.append({'robots': count, 'layout': label, 'outcome': result.outcome,
                             'sim_time_s': round(result.sim_time_s, 2),
                             'wall_time_s': round(result.wall_time_s, 2),
                             'real_time_factor': round(rtf, 3),
                             'robot_seconds_per_wall_s': round(robot_seconds, 2),
                             'against_one_robot': round(against_one, 3)})
                print(f'{count:3d} robots  {label:24s} {result.outcome:8s} '
                      f'{result.sim_time_s:7.2f} s sim in {result.wall_time_s:6.1f} s wall: '
                      f'{rtf:6.2f}x real time, {robot_seconds:5.1f} robot-s per wall s '
                      f'({against_one:.2f} of one robot\'s)', file=out, flush=True)
    met = []
    for robots, layout, least in TARGETS:
        row = next((row for row in rows
                    if row['robots'] == robots and row['layout'] == layout), None)
        if row is not None:
            reached = float(row['real_time_factor'])  # type: ignore[arg-type]
            met.append({'robots': robots, 'layout': layout, 'target_rtf': least,
                        'reached_rtf': reached, 'met': reached >= least})
            print(f'target: {robots} robots, {layout}: {reached:.2f}x real time '
                  f'(>= {least:g}x: {"met" if reached >= least else "NOT met"})', file=out)
    bad = [row for row in rows if row['outcome'] not in ('done', 'timeout')]
    for row in bad:
        print(f'{row["robots"]} robots, {row["layout"]}: ended {row["outcome"]}, not as drawn',
              file=sys.stderr)
    if args.json:
        print_json({'sim_seconds': args.sim_seconds, 'seed': args.seed, 'runs': rows,
                    'targets': met})
    return 1 if bad else 0
