"""docs/fleet.md's robots.yaml and tasks.yaml through the node graph, as its command line gives
them (``run --robots robots.yaml --tasks tasks.yaml --rtf 2 --json``), as fast as the lockstep
allows: the run is the same at any --rtf (test_fleet_graph.py shows it byte for byte). The
page's line on rendered images is taken up to the graph in tests/cli/test_docs_examples.py
(a run of two robots on images: test_fleet_images.py); its line on the bench needs drivers:
test_fleet_bench_loop.py runs the same options against stand-ins."""

from __future__ import annotations

import json
import os
import subprocess

import pytest
from conftest import ROOT
from docs_examples import DOCS, documented_command_lines, documented_file

# The bench's line needs drivers: test_fleet_bench_loop.py runs it against stand-ins.
GRAPH_LINES = [argv for argv in documented_command_lines((DOCS / 'fleet.md').read_text())
               if argv[0] == 'run' and 'tasks.yaml' in argv and '--vision' not in argv
               and '--camera' not in argv]


def test_the_page_runs_its_files_through_the_graph():
    assert len(GRAPH_LINES) == 1   # --rtf 2 --json


@pytest.mark.parametrize('line', GRAPH_LINES, ids=lambda argv: ' '.join(argv[5:]))
def test_the_fleet_page_s_files_run_through_the_graph_as_printed(line, tmp_path):
    for name in ('robots.yaml', 'tasks.yaml'):
        (tmp_path / name).write_text(documented_file(DOCS / 'fleet.md', name))
    ran = subprocess.run([str(ROOT / 'scripts' / 'omni-micro'), *line, '--rtf', 'max'],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300,
                         env=dict(os.environ))
    assert ran.returncode == 0, ran.stderr
    assert 'done: every task done' in (ran.stderr if '--json' in line else ran.stdout)
    if '--json' in line:
        summary = json.loads(ran.stdout)
        assert [robot['goals_reached'] for robot in summary['robots']] == [2, 1]
    if '--record' in line:
        bag = tmp_path / line[line.index('--record') + 1]
        assert (bag / 'metadata.yaml').exists() and list(bag.glob('*.mcap'))
