"""Every flag of every subcommand says what it does, and the exit codes are the README's."""

from __future__ import annotations

import argparse
import re

import pytest
from import_probe import HEAVY, loaded_after

from omni_micro_cli.cli import COMMANDS, build_parser


def subcommands() -> dict[str, argparse.ArgumentParser]:
    parser = build_parser()
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(action.choices)


@pytest.mark.parametrize('name', sorted(subcommands()))
def test_every_flag_has_help(name):
    missing = [action.option_strings or action.dest for action in subcommands()[name]._actions
               if not isinstance(action, argparse._HelpAction)
               and (not action.help or action.help == argparse.SUPPRESS)]
    assert not missing, f'{name}: {missing} have no help text'


@pytest.mark.parametrize(('name', 'codes'), [
    ('run', (0, 1, 2)), ('demo', (0, 1, 2)), ('soak', (0, 1, 2)), ('track', (0, 1, 2)),
    ('identify', (0, 1, 2)), ('calibrate-camera', (0, 1, 2)), ('record-target', (0, 2))])
def test_help_gives_the_exit_codes(name, codes):
    """Each code the command can end with, said as the README says them: 0 when done, 1 when
    the work failed, 2 for a bad argument."""
    text = ' '.join(subcommands()[name].format_help().split())
    stated = text.split('Exit 0', 1)[1] if 'Exit 0' in text else ''
    assert stated, f'{name}: no "Exit 0" in its help'
    said = {1: re.search(r'\b1 (when|otherwise)\b', stated) is not None,
            2: re.search(r'\b2 for a bad argument\b', stated) is not None}
    assert {code for code, found in said.items() if found} == set(codes) - {0}, stated[:200]


def test_analyse_is_analyze():
    commands = subcommands()
    assert commands['analyse'] is commands['analyze']


@pytest.mark.parametrize('argv', [['--help'], ['no-such-command'], ['analyse', '--help'],
                                  *([name, '--help'] for name in COMMANDS)])
def test_help_loads_no_heavy_library(argv):
    code = ('import contextlib, io\nfrom omni_micro_cli.cli import main\n'
            'with contextlib.redirect_stdout(io.StringIO()), '
            'contextlib.redirect_stderr(io.StringIO()):\n'
            f'    try:\n        main({argv!r})\n    except SystemExit:\n        pass')
    assert loaded_after(code, HEAVY) == []
