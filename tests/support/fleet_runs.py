"""A micro-factory run from a robots file and a tasks file through the graph, as the docs show
it (`run --robots FILE --tasks FILE`), and the check that two such runs are the same."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path


def run_fleet_files(omni_micro: Callable, folder: Path, robots: str, tasks: str,
                    *arguments: str) -> dict:
    """``robots`` and ``tasks`` (YAML) written into ``folder`` and run with ``arguments``, the
    bag recorded into ``folder/bag`` and the logs into ``folder/logs``: the run's JSON."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / 'robots.yaml').write_text(robots)
    (folder / 'tasks.yaml').write_text(tasks)
    done = omni_micro('run', '--robots', str(folder / 'robots.yaml'), '--tasks',
                      str(folder / 'tasks.yaml'), '--log-dir', str(folder / 'logs'),
                      '--record', str(folder / 'bag'), '--json', *arguments)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def assert_same_run_and_bag(reference: Path, other: Path, other_summary: dict) -> None:
    """The same JSON as ``reference/summary.json`` but its wall times, and the same bag file,
    byte for byte."""
    first = json.loads((reference / 'summary.json').read_text())
    second = dict(other_summary)
    for summary in (first, second):
        del summary['wall_s'], summary['planning_s'], summary['running_wall_s']
    assert second == first
    (recorded,) = (reference / 'bag').glob('*.mcap')
    assert (other / 'bag' / recorded.name).read_bytes() == recorded.read_bytes()
