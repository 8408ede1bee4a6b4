"""The command line's verbs stand apart: each parses, calls a library and prints, and what two
of them share lives beside them (graph_arguments.py, fleet_runs.py), not in one verb for another
to import."""

from __future__ import annotations

import ast
from pathlib import Path

from omni_micro_cli.cli import COMMANDS

COMMANDS_FOLDER = (Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src' / 'omni_micro_cli'
                   / 'omni_micro_cli' / 'commands')


def commands_imported(source: str) -> set[str]:
    """The modules of omni_micro_cli.commands that ``source`` imports, anywhere in it."""
    package = 'omni_micro_cli.commands'
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ImportFrom) and node.module == package:
            found |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module and \
                node.module.startswith(f'{package}.'):
            found.add(node.module.removeprefix(f'{package}.'))
        elif isinstance(node, ast.Import):
            found |= {alias.name.removeprefix(f'{package}.') for alias in node.names
                      if alias.name.startswith(f'{package}.')}
    return found


def test_no_command_imports_another():
    verbs = {command.module for command in COMMANDS.values()}
    built_on = {verb: sorted((commands_imported(path.read_text()) & verbs) - {verb})
                for verb in verbs
                if (path := COMMANDS_FOLDER / f'{verb.replace(".", "/")}.py').is_file()}
    assert {verb: others for verb, others in built_on.items() if others} == {}


def test_the_command_check_sees_an_import_in_a_function():
    assert commands_imported('def run():\n    from omni_micro_cli.commands import figures\n') \
        == {'figures'}
    assert commands_imported('from omni_micro_cli.commands.fleet import planned\n') == {'fleet'}
    assert commands_imported('from omni_micro_cli.outputs import atomic_bytes\n') == set()
