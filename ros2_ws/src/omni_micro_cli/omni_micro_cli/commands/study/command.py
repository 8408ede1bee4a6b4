"""`omni-micro study STUDY.yaml --out DIR`: run a study file's runs and report them."""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import Any

from omni_micro_cli.arguments import (
    STEERING_CHOICES,
    add_dask_arguments,
    check_dask_arguments,
)
from omni_micro_cli.errors import StudyError, UsageError
from omni_micro_cli.outputs import output_folder

EXAMPLE = Path(__file__).with_name('example.yaml')


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'study',
        description='Run every run of a study file through the in-process twin of the graph '
                    '(closed loop) or the slip core (open loop), on a Dask LocalCluster or an '
                    'existing scheduler. Writes DIR/runs.parquet (one row per run: inputs, '
                    'seed, metrics), DIR/summary.csv, DIR/summary.md and DIR/figure.png. '
                    'Ctrl-C keeps every finished run; --resume DIR finishes the rest.',
        epilog='Start with: omni-micro study --example > my-study.yaml')
    parser.add_argument('study', nargs='?', type=Path, metavar='STUDY.yaml',
                        help='the study file, or - for standard input (see --example and the '
                             'README for the schema)')
    parser.add_argument('--out', type=output_folder, metavar='DIR',
                        help='a new directory for the results (required with STUDY.yaml)')
    what = parser.add_mutually_exclusive_group()
    what.add_argument('--example', action='store_true',
                      help='print a small commented closed-loop Monte Carlo study and exit')
    what.add_argument('--resume', type=Path, metavar='DIR',
                      help='finish an interrupted study without redoing its finished runs')
    what.add_argument('--rerun', nargs=2, metavar=('DIR', 'ROW'),
                      help="run one row of a study again, alone, and compare with its result")
    add_dask_arguments(parser)
    parser.add_argument('--steering', choices=STEERING_CHOICES,
                        help="every run's steering motion, as the file's steering: key says "
                             '(ideal: the paper, the default; realistic: motor limits, backlash, '
                             'pivot friction, with the backlash_deg, contact_radius_um and '
                             'steering_rate_deg_s parameters)')
    parser.add_argument('--serial', action='store_true',
                        help='no Dask: a plain loop in this process (the reference)')
    parser.set_defaults(handler=run)


def _check(args: argparse.Namespace) -> None:
    if args.example or args.rerun:
        if args.study is not None or args.out is not None:
            raise UsageError('--example and --rerun take no STUDY.yaml or --out')
        return
    if args.resume is not None:
        if args.study is not None or args.out is not None:
            raise UsageError('--resume DIR takes no STUDY.yaml or --out: the study is the one '
                             'DIR was started with')
    elif args.study is None or args.out is None:
        raise UsageError('give STUDY.yaml and --out DIR (or --example, --resume DIR, '
                         '--rerun DIR ROW)')
    if args.steering and args.study is None:
        raise UsageError('--steering sets a new study\'s steering: give STUDY.yaml (a resumed '
                         'or rerun study keeps its own)')
    if args.serial and (args.scheduler or args.workers):
        raise UsageError('--serial runs in this process: no --workers or --scheduler')
    check_dask_arguments(args)


def run(args: argparse.Namespace) -> int:
    from omni_micro_studies import execute as execution
    from omni_micro_studies.report import write_figure, write_summary
    from omni_micro_studies.spec import (
        check_steering_parameters,
        load_study,
        parse_study,
    )

    _check(args)
    if args.example:
        print(EXAMPLE.read_text(), end='')
        return 0
    try:
        if args.rerun:
            return rerun(Path(args.rerun[0]), args.rerun[1])
        if args.resume is not None:
            out = args.resume
            study = execution.load_directory(out)
        else:
            out = args.out
            study = (parse_study(_stdin_text(), 'stdin') if str(args.study) == '-'
                     else load_study(args.study))
            if args.steering and args.steering != study.steering:
                study = with_steering(study, args.steering, parse_study)
            check_steering_parameters(study)
            created = not out.exists()
            execution.prepare_directory(study, out)
    except StudyError as error:
        raise UsageError(str(error)) from None
    workers = args.workers or os.cpu_count() or 1
    print(f'study {study.name}: {study.run_count} runs ({study.points} points x '
          f'{study.seeds_per_point} seeds x {len(study.modes)} modes) -> {out}/',
          file=sys.stderr)
    try:
        done = execution.execute(study, out, workers=workers, scheduler=args.scheduler,
                                 scheduler_timeout_s=args.scheduler_timeout,
                                 serial=args.serial)
    except KeyboardInterrupt:
        kept = len(execution.finished_rows(study, out))
        print(f'study: interrupted: {kept} of {study.run_count} runs kept in {out}/; '
              f'./scripts/omni-micro study --resume {out} finishes it', file=sys.stderr)
        return 130
    except StudyError as error:
        if args.resume is None and not execution.finished_rows(study, out):
            execution.forget_directory(out, created)   # nothing ran: nothing is left
        raise UsageError(str(error)) from None
    try:
        table = execution.collect(study, out)
    except StudyError as error:
        raise UsageError(str(error)) from None
    rows = table.to_pylist()
    text = write_summary(study, rows, out)
    drawn = write_figure(study, rows, out / 'figure.png')
    print(text)
    rate = done.ran / done.wall_s if done.wall_s > 0 else math.inf
    resumed = f' (resumed: {done.already_done} were done)' if done.already_done else ''
    print(f'{done.ran} runs in {done.wall_s:.1f} s ({rate:.1f} runs/s) on {done.where}'
          f'{resumed}; rows, summary{" and figure" if drawn else ""} in {out}/',
          file=sys.stderr)
    return 0


def with_steering(study: Any, steering: str, parse: Any) -> Any:
    """The study with ``steering`` (--steering), its kept text saying so too: a resumed study
    must run what this one ran."""
    import yaml

    if 'steering' in (yaml.safe_load(study.text) or {}):
        raise UsageError(f'the study file says steering: {study.steering}; --steering '
                         f'{steering} disagrees: change one')
    text = study.text.rstrip('\n') + f'\nsteering: {steering}   # set by --steering\n'
    return parse(text, study.name)


def _stdin_text() -> str:
    try:
        return sys.stdin.read()
    except UnicodeDecodeError as error:
        raise StudyError(f'stdin: not UTF-8 text (byte {error.start}); a study file is YAML') \
            from None


def rerun(out: Path, row_text: str) -> int:
    """Run row ``row_text`` of the study in ``out`` again and compare its metrics."""
    from omni_micro_studies import execute as execution
    from omni_micro_studies.runs import run_row

    study = execution.load_directory(out)
    try:
        index = int(row_text)
    except ValueError:
        raise StudyError(f'ROW: expected a run number, got {row_text!r}') from None
    if not 0 <= index < study.run_count:
        raise StudyError(f'ROW: expected a run number in [0, {study.run_count - 1}], got '
                         f'{index}')
    kept = {row['run']: row for row in execution.finished_rows(study, out)}
    inputs = study.runs()[index]
    again = run_row(inputs, study.metric_columns)
    print(f'run {index} of {study.name}: mode {inputs["mode"]}, seed {inputs["seed"]}')
    for name in study.swept:
        print(f'  {name} = {inputs[name]:.6g}')
    before = kept.get(index)
    differences = []
    for column in [*study.metric_columns, 'error']:
        now = again[column]
        line = f'  {column}: {_show(now)}'
        if before is not None:
            line += f'   (kept: {_show(before[column])})'
            if before[column] != now:
                differences.append(column)
        print(line)
    if before is None:
        print('  (this run was not finished in the study: nothing to compare)')
        return 0
    if differences:
        print(f'  differs from the kept row in: {", ".join(differences)}')
        return 1
    print('  identical to the kept row')
    return 0


def _show(value: Any) -> str:
    return f'{value:.6g}' if isinstance(value, float) else str(value)

