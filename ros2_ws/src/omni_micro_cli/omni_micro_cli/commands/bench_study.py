"""`omni-micro bench-study`: how fast studies run, against a plain loop measured in the same run.

Three measurements of the example's closed-loop Monte Carlo (Fig. 11's goal, random xi2, xi3,
the paper's rule), all through :func:`omni_micro_studies.execute.execute`:

1. a plain loop in this process (no Dask) over ``--runs`` runs: the reference;
2. the same runs on a LocalCluster of 1 worker, then of 2: throughput and its scaling, and the
   scheduling overhead per run (the 1-worker time less the loop's, per run);
3. a ``--big`` run study on the default cluster, timed as the user would (cluster start
   included): target under 60 s for 1,000 runs on this 2-core machine.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from omni_micro_cli.arguments import whole_number_in
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import print_json

if TYPE_CHECKING:
    from omni_micro_studies.execute import Execution
    from omni_micro_studies.spec import Study


EXAMPLE = Path(__file__).with_name('study') / 'example.yaml'


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bench-study',
        description=__doc__.split('\n\n', 1)[1].replace('\n', ' '))
    parser.add_argument('--runs',
                        type=whole_number_in(0, 1_000_000), default=200, metavar='N',
                        help='runs of the loop and scaling measurements (default 200)')
    parser.add_argument('--big',
                        type=whole_number_in(0, 10_000_000), default=1000, metavar='N',
                        help='runs of the timed whole study (default 1000; 0 skips it)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the rest on stderr)')
    parser.set_defaults(handler=run)


def monte_carlo(runs: int) -> Study:
    from omni_micro_studies.spec import parse_study

    text = EXAMPLE.read_text().replace('draws: 24', f'draws: {runs}').replace(
        'seeds_per_point: 2', 'seeds_per_point: 1')
    study = parse_study(text, 'bench')
    assert study.run_count == runs, study.run_count
    return study


def timed(study: Study, **how: object) -> Execution:
    from omni_micro_studies.execute import execute, prepare_directory

    with tempfile.TemporaryDirectory(prefix='omni-micro-bench-study-') as scratch:
        out = Path(scratch) / 'study'
        prepare_directory(study, out)
        return execute(study, out, progress=False, **how)   # type: ignore[arg-type]


def run(args: argparse.Namespace) -> int:
    if args.runs < 10:
        raise UsageError(f'--runs: expected at least 10 runs to time, got {args.runs}')
    cores = os.cpu_count() or 1
    study = monte_carlo(args.runs)
    figures: dict[str, float] = {'runs': args.runs, 'cores': cores}

    def report(key: str, value: float, line: str) -> None:
        figures[key] = value
        print(line, flush=True)

    print(f'bench-study: {args.runs} closed-loop runs (Fig. 11 goal, random xi2, xi3, paper\'s '
          f'rule) on {cores} cores', file=sys.stderr)
    runs = args.runs
    loop = timed(study, workers=1, serial=True).compute_s
    report('loop_ms_per_run', 1e3 * loop / runs,
           f'plain loop (no Dask):   {loop:6.2f} s, {1e3 * loop / runs:6.1f} ms per run')
    one = timed(study, workers=1)
    two = timed(study, workers=2)
    # Throughput on warm workers: starting a cluster is a fixed cost, reported apart.
    report('one_worker_runs_per_s', runs / one.compute_s,
           f'LocalCluster 1 worker:  {one.compute_s:6.2f} s, {runs / one.compute_s:6.1f} '
           f'runs/s (+ {one.wall_s - one.compute_s:.1f} s to start the cluster)')
    report('two_workers_runs_per_s', runs / two.compute_s,
           f'LocalCluster 2 workers: {two.compute_s:6.2f} s, {runs / two.compute_s:6.1f} '
           f'runs/s (+ {two.wall_s - two.compute_s:.1f} s to start the cluster)')
    report('scaling_2_over_1', one.compute_s / two.compute_s,
           f'scaling 2 workers / 1:  {one.compute_s / two.compute_s:6.2f}x (target >= 1.8x)')
    overhead = (one.compute_s - loop) / runs
    report('overhead_ms_per_run', 1e3 * overhead,
           f'Dask overhead per run:  {1e3 * overhead:6.2f} ms ({100 * overhead * runs / loop:.1f}'
           ' % of a run; 1 worker against the plain loop)')
    if args.big:
        big = timed(monte_carlo(args.big), workers=cores).wall_s
        report('big_study_s', big,
               f'{args.big}-run study:       {big:6.1f} s on {cores} workers, cluster start '
               'included (target < 60 s for 1,000)')
    if args.json:
        print_json(figures)
    return 0
