"""The static checks CI runs before the tests: they run, and they catch what they are for."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
VENV_BIN = Path(sys.executable).parent


def test_the_test_command_runs_the_static_checks_first():
    test_script = (ROOT / 'scripts' / 'test').read_text()
    assert test_script.index('scripts/lint') < test_script.index('pytest')
    assert './scripts/test' in (ROOT / '.ci' / 'run').read_text()


def test_ruff_with_the_project_rules_catches_the_issue_kinds(tmp_path):
    probe = tmp_path / 'probe.py'
    probe.write_text(
        'import sys\nimport os\n\n\n'                       # I001 unsorted imports
        'def f(items):\n'
        '    out = []\n'
        '    for item in items:\n'
        '        out.append(lambda: item)\n'                 # B023 loop variable in a closure
        '    return list(zip(items, out)), os, sys\n')     # B905 zip() without strict=
    result = subprocess.run([str(VENV_BIN / 'ruff'), 'check', '--config',
                             str(ROOT / 'pyproject.toml'), '--no-cache', str(probe)],
                            capture_output=True, text=True)
    assert result.returncode == 1
    for code in ('I001', 'B023', 'B905'):
        assert code in result.stdout, result.stdout


def test_mypy_is_strict_on_the_plain_modules(tmp_path):
    """A plain module's function without annotations is refused; elsewhere it is only checked."""
    package = tmp_path / 'omni_micro_common'
    package.mkdir()
    (package / '__init__.py').write_text('')
    (package / 'lockstep.py').write_text('def gate(nodes):\n    return nodes\n')
    env = dict(os.environ, MYPYPATH='')
    result = subprocess.run(
        [str(VENV_BIN / 'mypy'), '--config-file', str(ROOT / 'pyproject.toml'),
         '--python-executable', sys.executable, '--no-incremental', '--no-error-summary',
         str(package / 'lockstep.py')], capture_output=True, text=True, cwd=tmp_path, env=env)
    assert result.returncode == 1 and 'no-untyped-def' in result.stdout, result.stdout


def test_readme_figures_are_read_from_their_table_rows():
    sys.path.insert(0, str(ROOT / 'scripts' / 'lib'))
    from readme_figures import readme_range

    readme = ('| measure | figure |\n| speed-up (target 50x) | **56.9-58.3x** |\n'
              '| one | 0.64 ms |\n')
    assert readme_range(readme, 'speed-up') == (56.9, 58.3)
    assert readme_range(readme, 'one') == (0.64, 0.64)
