"""The docs' examples as a newcomer types them: every ``omni-micro`` command line in docs/ and
README.md is taken by the command's parser, and docs/fleet.md's robots.yaml and tasks.yaml run
as printed (in the twin here; through the graph: tests/graph/test_docs_fleet_examples.py, and
the line on rendered images up to the graph here)."""

from __future__ import annotations

import contextlib
import io
import json
import re
import shlex

import pytest
from docs_examples import DOCS, PAGES, documented_command_lines, documented_file

from omni_micro_cli.cli import build_parser, command_named, main


def test_the_extraction_finds_the_command_lines_of_the_pages():
    found = documented_command_lines(
        '```bash\n./scripts/omni-micro run --goal-mm 1,2 \\\n    --seed 3   # why\n'
        'omni-micro figures [--out DIR] | tee x\n$ omni-micro run ...\n```\n')
    assert found == [['run', '--goal-mm', '1,2', '--seed', '3'], ['figures', '--out', 'DIR']]
    assert sum(len(documented_command_lines(page.read_text())) for page in PAGES) > 80


@pytest.mark.parametrize('page', PAGES, ids=lambda page: page.name)
def test_every_documented_command_line_is_taken_by_its_command(page):
    for argv in documented_command_lines(page.read_text()):
        said = io.StringIO()
        try:
            with contextlib.redirect_stderr(said), contextlib.redirect_stdout(io.StringIO()):
                _, unknown = build_parser(command_named(argv) or '').parse_known_args(argv)
        except SystemExit as refused:
            assert not refused.code, f'{page.name}: omni-micro {shlex.join(argv)}: {said}'
            continue
        assert not unknown, f'{page.name}: omni-micro {shlex.join(argv)} takes no {unknown}'


@pytest.fixture
def fleet_files(tmp_path, monkeypatch):
    """docs/fleet.md's robots.yaml and tasks.yaml, written where the commands run."""
    for name in ('robots.yaml', 'tasks.yaml'):
        (tmp_path / name).write_text(documented_file(DOCS / 'fleet.md', name))
    monkeypatch.chdir(tmp_path)
    return tmp_path


def test_the_fleet_page_s_robots_and_tasks_run_as_printed(fleet_files, capsys):
    line = next(argv for argv in documented_command_lines((DOCS / 'fleet.md').read_text())
                if argv[0] == 'fleet' and 'tasks.yaml' in argv)
    assert main(line) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['outcome'] == 'done'
    assert [robot['goals_reached'] for robot in summary['robots']] == [2, 1]


def test_a_tolerance_finer_than_the_seeing_camera_resolves_is_refused_writing_nothing(
        fleet_files, capsys):
    tasks = fleet_files / 'tasks.yaml'
    tasks.write_text(re.sub(r'tolerance_um: \d+', 'tolerance_um: 20', tasks.read_text()))
    bag = fleet_files / 'bags' / 'fleet'
    assert main(['fleet', '--robots', 'robots.yaml', '--tasks', 'tasks.yaml',
                 '--record', str(bag)]) == 2
    said = capsys.readouterr().err.strip()
    assert said == ("omni-micro fleet: error: robot 1's goal 0 at (0, 0) mm: tolerance_um 20 is "
                    'finer than the macro camera that sees it resolves (+-26.39 um at 95 %): '
                    'give more than 26.39, or leave it out (the default: 50 um there)')
    assert not (fleet_files / 'bags').exists()
    # In the micro field a tolerance as fine is resolved many times over: taken.
    tasks.write_text(tasks.read_text().replace('tolerance_um: 20', 'tolerance_um: 100')
                     .replace('goal_mm: [100, 0.2]', 'goal_mm: [100, 0.2]\n      '
                              'tolerance_um: 2'))
    assert main(['fleet', '--robots', 'robots.yaml', '--tasks', 'tasks.yaml',
                 '--max-sim-time', '1']) == 1   # planned and run (it times out)
    assert 'timeout: tasks left after 1 s' in capsys.readouterr().err


def test_the_fleet_page_s_line_on_images_hands_the_graph_its_files(fleet_files, monkeypatch,
                                                                   capsys):
    """``run --robots robots.yaml --tasks tasks.yaml --vision images --record ...`` is taken,
    checked and planned, and reaches the graph with the robots' controllers on images."""
    from omni_micro_bringup import graph
    from omni_micro_bringup.graph_result import GraphResult, RobotLog

    line = next(argv for argv in documented_command_lines((DOCS / 'fleet.md').read_text())
                if argv[0] == 'run' and 'tasks.yaml' in argv and '--vision' in argv)
    asked = []

    def run_graph(options):
        asked.append(options)
        logs = [RobotLog(tasks_done_s=[1.0] * len(tasks), route=[(0.0, 0.0, 0.0, 0.0)])
                for tasks in options.fleet.plan.tasks]
        return GraphResult('done', 'every task done in 1.00 s', 1.0, 0.5, options.log_dir, 7,
                           robots=logs, closest_gap_m=0.02, closest_pair=(0, 1))

    monkeypatch.setattr(graph, 'run_graph', run_graph)
    assert main(line) == 0, capsys.readouterr().err
    (options,) = asked
    assert options.vision == 'images' and options.record is not None
    assert options.fleet.controllers == ['model', 'paper']
