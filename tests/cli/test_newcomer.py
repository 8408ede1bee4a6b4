"""What a newcomer following docs/fleet.md meets: ``--json`` gives standard output as the JSON
document alone (the table and progress on standard error), and a hint a message gives works
(an existing bag: ``--force`` replaces it)."""

from __future__ import annotations

import json
import sys

import pytest

from omni_micro_cli.cli import main
from omni_micro_cli.outputs import json_alone_on_stdout, print_json

FLEET = ['fleet', '--robots', '2', '--goals-per-robot', '1', '--seed', '0']


def test_with_json_standard_output_is_the_json_document_alone(capsys):
    assert main([*FLEET, '--json']) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)   # the whole of it: one document, nothing around it
    assert summary['outcome'] == 'done' and len(summary['robots']) == 2
    assert 'robot_0  paper' in err and 'goals reached at' in err
    assert main(['simulate', '--theta-deg', '0', '--duration', '2', '--json']) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)['drift_mm'] > 0


def test_without_json_the_table_stays_on_standard_output(capsys):
    assert main(FLEET) == 0
    out, err = capsys.readouterr()
    assert 'robot_0  paper' in out and 'goals reached at' in err


def test_only_print_json_reaches_standard_output_under_json(capsys):
    with json_alone_on_stdout():
        print('a table')
        print_json({'a': 1})
        print('more', file=sys.stdout)
    out, err = capsys.readouterr()
    assert out == '{"a": 1}\n' and err == 'a table\nmore\n'


@pytest.mark.parametrize('door', [FLEET, ['run', '--robots', '2']])
def test_the_force_an_existing_bag_s_message_names_is_taken(door, tmp_path, capsys):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    assert main([*door, '--record', str(bag)]) == 2
    err = capsys.readouterr().err
    assert 'exists already; give --force to replace it' in err
    assert (bag / 'metadata.yaml').exists()   # refused: nothing touched
    if door[0] == 'fleet':   # the twin writes its bag itself: replaced by a readable one
        assert main([*door, '--record', str(bag), '--force']) == 0
        assert 'recorded' in capsys.readouterr().err
        assert list(bag.glob('*.mcap'))
    else:   # through the graph: the flag is taken (the run itself is tests/graph's)
        assert main([*door, '--record', str(bag), '--force', '--tasks',
                     str(tmp_path / 'missing.yaml')]) == 2
        assert 'unknown' not in capsys.readouterr().err
