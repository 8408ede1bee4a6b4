"""`omni-micro bench-startup`: how long the command line takes to start, against the bare
interpreter measured in the same run.

Each case runs ``--repeats`` times as a fresh process (the installed console script, as a user
types it); the median wall time is reported beside the interpreter's own start-up (``python -c
pass``), so that the figures mean the same on a slower or busier machine. Targets: ``--help``
under 0.3 s and ``simulate`` (one 1 s move) under 0.7 s on the 2-core machine.
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from omni_micro_cli.arguments import whole_number_in
from omni_micro_cli.errors import RunFailed
from omni_micro_cli.outputs import print_json

CASES = (('omni-micro --help', ['--help']),
         ('omni-micro simulate --help', ['simulate', '--help']),
         ('omni-micro run --help', ['run', '--help']),
         ('omni-micro simulate (1 s move)', ['simulate', '--theta-deg', '0', '--duration', '1']))
TARGETS_S = {'omni-micro --help': 0.3, 'omni-micro simulate (1 s move)': 0.7}


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bench-startup', description=__doc__.split('\n\n', 1)[1].replace('\n', ' '))
    parser.add_argument('--repeats',
                        type=whole_number_in(1, 1000), default=7, metavar='N',
                        help='fresh processes per case; the median counts (default 7)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the rest on stderr)')
    parser.set_defaults(handler=run)


def median_wall_s(argv: list[str], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        began = time.perf_counter()
        done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                              timeout=120)
        times.append(time.perf_counter() - began)
        if done.returncode != 0:
            raise RunFailed(f'{" ".join(argv)} exited with {done.returncode}: '
                            f'{done.stderr.strip()[-300:]}')
    return statistics.median(times)


def run(args: argparse.Namespace) -> int:
    script = shutil.which('omni-micro', path=str(Path(sys.executable).parent))
    if script is None:
        raise RunFailed(f'no omni-micro console script beside {sys.executable}')
    reference = median_wall_s([sys.executable, '-c', 'pass'], args.repeats)
    print(f'{"case":34} {"median":>9} {"x python":>9}  target')
    print(f'{"python -c pass (reference)":34} {reference:8.3f}s {1.0:8.1f}x')
    figures = {'reference_s': reference}
    for name, argv in CASES:
        seconds = median_wall_s([script, *argv], args.repeats)
        figures[name] = seconds
        target = TARGETS_S.get(name)
        verdict = '' if target is None else (f'< {target:g} s: ' +
                                             ('met' if seconds < target else 'NOT met'))
        print(f'{name:34} {seconds:8.3f}s {seconds / reference:8.1f}x  {verdict}')
    if args.json:
        print_json(figures)
    return 0
