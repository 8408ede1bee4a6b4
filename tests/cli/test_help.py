"""Every flag of every subcommand says what it does, and the exit codes are the README's."""

from __future__ import annotations

import argparse

import pytest

from omni_micro_cli.cli import build_parser


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


@pytest.mark.parametrize('name', ['run', 'demo', 'soak'])
def test_help_gives_the_exit_codes(name):
    text = subcommands()[name].format_help()
    assert 'Exit 0' in text and '2' in text.split('Exit 0', 1)[1]


def test_analyse_is_analyze():
    commands = subcommands()
    assert commands['analyse'] is commands['analyze']
