"""`omni-micro demo`: the paper's open-loop scenarios through the slip core, beside its numbers.

Until the ROS node graph exists this runs the core directly (no ROS processes).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from omni_micro_sim import paper

from omni_micro_cli import figures
from omni_micro_cli.outputs import staged_directory


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'demo', help="the paper's open-loop results reproduced, with figures",
        description="Run the paper's open-loop scenarios (Figs. 6, 7, 8, 11) through the slip "
                    "core, print our numbers beside the paper's and write the figures.")
    parser.add_argument('--out', type=Path, default=Path('out/demo'), metavar='DIR',
                        help='where the figures go (default out/demo)')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    with staged_directory(args.out) as scratch:
        figures.write_figures(scratch, angle_step_deg=2.0, offset_step_deg=0.25)
        table = (scratch / 'comparison.md').read_text()
    print(table)
    print(f'figures in {args.out}/ ({time.perf_counter() - started:.1f} s); closed-loop '
          f'(paper: {paper.FIG11_PUBLISHED_CLOSED_LOOP_DEVIATION_MM} mm) needs the node graph.')
    return 0
