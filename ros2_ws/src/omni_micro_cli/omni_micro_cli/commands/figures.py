"""`omni-micro figures`: the paper's Figs. 6, 7, 8(a)(b)(c) and the open-loop route of Fig. 11."""

from __future__ import annotations

import argparse
import math
import sys
import time

from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import output_folder, staged_directory
from omni_micro_sim import paper
from omni_micro_studies.open_loop_figures import write_figures

# Fig. 6's full turn at this step is 36,001 moves: the finest grid anyone plots.
MIN_STEP_DEG = 0.01


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'figures',
        description="Reproduce Figs. 6, 7, 8(a)(b)(c) and the open-loop route of Fig. 11 as PNG "
                    "files and write comparison.md (the paper's numbers beside ours) and "
                    "figures.json into DIR.")
    parser.add_argument('--out', type=output_folder, required=True, metavar='DIR',
                        help='output directory (created; files of the same name are replaced)')
    parser.add_argument('--angle-step-deg', type=float, default=1.0, metavar='DEG',
                        help='direction-angle resolution of Fig. 6 (default 1)')
    parser.add_argument('--offset-step-deg', type=float, default=0.1, metavar='DEG',
                        help='offset resolution of Fig. 7 (default 0.1)')
    parser.set_defaults(handler=run)


def progress(message: str) -> None:
    print(f'[figures] {message}', file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:

    for name in ('angle_step_deg', 'offset_step_deg'):
        value = getattr(args, name)
        if not math.isfinite(value) or not MIN_STEP_DEG <= value <= 30.0:
            raise UsageError(
                f'--{name.replace("_", "-")} must be in [{MIN_STEP_DEG:g}, 30] degrees (Fig. 6 '
                f'at {MIN_STEP_DEG:g} deg is already 36,001 moves), got {value!r}')
    started = time.perf_counter()
    with staged_directory(args.out) as scratch:
        numbers = write_figures(scratch, args.angle_step_deg, args.offset_step_deg, progress)
        written = sorted(path.name for path in scratch.iterdir())   # not the user's own files
    progress(f'done in {time.perf_counter() - started:.1f} s: {args.out}')
    print(f'fig. 8 drift: {numbers["fig8_drift_mm"]:.4f} mm '
          f'(paper {paper.FIG8_PUBLISHED_DRIFT_MM} mm)')
    print(f'fig. 11 open-loop deviation: {numbers["fig11_open_loop_deviation_mm"]:.3f} mm '
          f'(paper {paper.FIG11_PUBLISHED_OPEN_LOOP_DEVIATION_MM:g} mm)')
    print(f'wrote {", ".join(written)}')
    return 0
