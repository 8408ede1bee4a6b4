"""The benchmark tables of the README and the docs site against a fresh run
(./scripts/check-readme-figures)."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
# Timings on a shared 2-core machine: a fresh figure within half to twice the README's passes.
TIMING_FACTOR = 2.0


def readme_range(readme: str, row_start: str) -> tuple[float, float]:
    """The first number or range (a-b) in the README table row that starts with row_start."""
    row = next(line for line in readme.splitlines() if line.startswith(f'| {row_start}'))
    figure = row.rsplit('|', 2)[1]
    match = re.search(r'([\d.]+)(?:-([\d.]+))?', figure.replace('**', ''))
    if match is None:
        raise ValueError(f'no figure in the README row {row!r}')
    low = float(match.group(1))
    return low, float(match.group(2) or low)


def command_json(*args: str) -> dict[str, Any]:
    result = subprocess.run([str(Path(sys.executable).parent / 'omni-micro'), *args, '--json'],
                            capture_output=True, text=True, check=True, cwd=ROOT)
    return dict(json.loads(result.stdout.strip().splitlines()[-1]))


def main() -> int:
    # The tables live where the text about them does: the README or a page of docs/.
    readme = '\n'.join(path.read_text() for path in [ROOT / 'README.md',
                                                       *sorted((ROOT / 'docs').glob('*.md'))])
    bench = command_json('bench')
    checks = [  # README row, fresh figure, in the README's unit
        ('reference: `solve_ivp', float(bench['reference_lsoda_s']) * 1e3),
        ('slip core, one 7 s move', float(bench['core_single_run_s']) * 1e3),
        ('speed-up against the reference', float(bench['speedup_vs_reference'])),
        ('batch of 1000 open-loop moves', float(bench['batch_s'])),
    ]
    stale = []
    for row, fresh in checks:
        low, high = readme_range(readme, row)
        ok = low / TIMING_FACTOR <= fresh <= high * TIMING_FACTOR
        print(f'{"ok   " if ok else "STALE"} {row}: README {low:g}-{high:g}, now {fresh:.3g}')
        if not ok:
            stale.append(row)
    # The graph table: its timings vary too much on this machine to check, but its lockstep rows
    # are deterministic: the same final x as in the README, to the digits shown, at every load.
    graph = command_json('bench-graph')
    for run in graph['runs']:
        if run['case'].startswith('lockstep'):
            row = next(line for line in readme.splitlines()
                       if line.startswith(f'| {run["case"].replace("--rtf max", "`--rtf max`")}'))
            expected = row.rsplit('|', 2)[1].strip()
            ok = run['outcome'] == 'reached' and f'{run["final_x_mm"]:.7f}' == expected
            print(f'{"ok   " if ok else "STALE"} {run["case"]}: README x {expected} mm, now '
                  f'{run["final_x_mm"]:.7f} mm ({run["outcome"]}, rtf {run["rtf_reached"]})')
            if not ok:
                stale.append(run['case'])
    if stale:
        print(f'{len(stale)} README figure(s) stale: re-run the command named beside the table '
              f'and update them', file=sys.stderr)
        return 1
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
