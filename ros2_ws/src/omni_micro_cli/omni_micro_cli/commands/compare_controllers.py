"""`omni-micro compare-controllers`: the paper's rule, the model-based mode and the servo on
seeded cases (omni_micro_studies.controller_comparison says which)."""

from __future__ import annotations

import argparse
import json
import sys
import time

from omni_micro_cli.arguments import (
    add_dask_arguments,
    add_steering_argument,
    check_dask_arguments,
    positive_float,
    seed_number,
    whole_number_in,
)
from omni_micro_cli.outputs import output_folder, staged_directory
from omni_micro_studies import controller_comparison as comparison


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'compare-controllers',
        description=comparison.__doc__.split('\n\n', 1)[1].replace('\n', ' ')
        + ' Writes a table, a figure and one JSON row per case; prints the table. Exit 0 when '
          'done.')
    parser.add_argument('--cases',
                        type=whole_number_in(0, 1_000_000), default=100, metavar='N',
                        help='number of seeded cases (default 100)')
    parser.add_argument('--seed', type=seed_number, default=0, metavar='N',
                        help='seed of the cases (robots, starts, goals, camera noise)')
    parser.add_argument('--tolerance-um', type=positive_float, default=0.5, metavar='UM',
                        help='tolerance of both modes (default 0.5 um)')
    add_dask_arguments(parser)
    add_steering_argument(parser)
    parser.add_argument('--out', type=output_folder, default='out/compare-controllers',
                        metavar='DIR', help='where the table, figure and rows go')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    from omni_micro_studies.execute import map_on_dask, runs_go_to

    check_dask_arguments(args)
    cases = comparison.make_cases(args.cases, args.seed, args.steering)
    if not cases:
        print('compare-controllers: --cases 0: nothing to run', file=sys.stderr)
        return 0
    tolerance_m = args.tolerance_um * 1e-6
    print(f'compare-controllers: {len(cases)} cases on '
          f'{runs_go_to(args.workers, args.scheduler)}', file=sys.stderr)
    began = time.perf_counter()
    shown = 0.0

    def progress(done: int, _row: object) -> None:
        nonlocal shown
        elapsed = time.perf_counter() - began
        if elapsed - shown >= 0.5 or done == len(cases):   # a line twice a second at most
            shown = elapsed
            print(f'\rcompare-controllers: {done}/{len(cases)} cases, '
                  f'{done / elapsed:.1f}/s, {elapsed / done * (len(cases) - done):.0f} s '
                  f'left', end='', file=sys.stderr, flush=True)

    rows: list[dict] = map_on_dask(comparison.run_case,
                                   [(case, tolerance_m) for case in cases],
                                   workers=args.workers, scheduler=args.scheduler,
                                   scheduler_timeout_s=args.scheduler_timeout,
                                   on_result=progress)
    print(file=sys.stderr)
    summary = comparison.summarise(rows, args.tolerance_um)
    text = comparison.table(summary)
    with staged_directory(args.out) as scratch:
        (scratch / 'comparison.md').write_text(text)
        (scratch / 'summary.json').write_text(json.dumps(summary, indent=2))
        (scratch / 'cases.jsonl').write_text(''.join(
            json.dumps({k: v for k, v in row.items() if not k.endswith('_route_m')}) + '\n'
            for row in rows))
        comparison.figure(scratch / 'comparison.png', rows, args.tolerance_um)
    print(text)
    print(f'table, figure and rows in {args.out}/ ({time.perf_counter() - began:.1f} s)',
          file=sys.stderr)
    return 0
