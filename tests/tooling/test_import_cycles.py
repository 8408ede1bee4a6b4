"""The workspace's imports run one way. No two modules import each other, however indirectly:
every import counts, at the top, inside a function or under ``if TYPE_CHECKING:`` (a reader
follows each of them); a lower module that needs something of an upper one says what in a
``typing.Protocol``. And nothing but the command line's own tests imports the command line."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def workspace_modules(src: Path) -> dict[str, Path]:
    """Every module of the ament_python packages under ``src``, by dotted name."""
    found = {}
    for init in src.glob('*/*/__init__.py'):
        for path in init.parent.rglob('*.py'):
            parts = path.relative_to(init.parent.parent).with_suffix('').parts
            found['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    return found


def imported_modules(name: str, path: Path, known: dict[str, Path]) -> set[str]:
    """The workspace modules ``name`` imports anywhere in its file: ``from a import b`` counts
    as ``a.b`` where that is a module, else as ``a``."""
    package = name if path.name == '__init__.py' else name.rpartition('.')[0]
    imported = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:
                anchor = package.split('.')[:len(package.split('.')) - node.level + 1]
                base = '.'.join([*anchor, *([base] if base else [])])
            targets = [f'{base}.{alias.name}' if f'{base}.{alias.name}' in known else base
                       for alias in node.names]
        else:
            continue
        imported |= {target for target in targets if target in known and target != name}
    return imported


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(module: str) -> None:
        index[module] = low[module] = len(index)
        stack.append(module)
        on_stack.add(module)
        for other in sorted(graph[module]):
            if other not in index:
                visit(other)
                low[module] = min(low[module], low[other])
            elif other in on_stack:
                low[module] = min(low[module], index[other])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == module:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for module in sorted(graph):
        if module not in index:
            visit(module)
    return found


def import_graph(src: Path) -> dict[str, set[str]]:
    known = workspace_modules(src)
    return {name: imported_modules(name, path, known) for name, path in known.items()}


def test_the_workspace_has_no_import_circle():
    found = circles(import_graph(ROOT / 'ros2_ws' / 'src'))
    assert found == [], 'import circles: ' + '; '.join(' <-> '.join(c) for c in found)


def test_a_type_only_or_late_import_back_is_a_circle(tmp_path):
    """The check is real: an import under TYPE_CHECKING, or inside a function, closes one."""
    package = tmp_path / 'pkg' / 'pkg'
    package.mkdir(parents=True)
    (package / '__init__.py').write_text('')
    (package / 'upper.py').write_text('from pkg.lower import helper\n')
    (package / 'lower.py').write_text(
        'from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.upper import X\n')
    (package / 'alone.py').write_text('def f():\n    from . import late\n')
    (package / 'late.py').write_text('def g():\n    from .alone import f\n')
    assert circles(import_graph(tmp_path)) == [['pkg.alone', 'pkg.late'],
                                               ['pkg.lower', 'pkg.upper']]


def test_nothing_below_the_command_line_imports_it():
    """The command line is the top: its verbs call the packages, never the other way round,
    and only its own tests (tests/cli) import it."""
    sources = [*(ROOT / 'ros2_ws' / 'src').glob('*/*/**/*.py'), *(ROOT / 'tests').rglob('*.py')]
    cli = ROOT / 'ros2_ws' / 'src' / 'omni_micro_cli'
    importers = sorted(str(path.relative_to(ROOT)) for path in sources
                       if cli not in path.parents and ROOT / 'tests' / 'cli' not in path.parents
                       and any(name == 'omni_micro_cli' or name.startswith('omni_micro_cli.')
                               for name in top_imports(path)))
    assert importers == []


def top_imports(path: Path) -> set[str]:
    """Every module name ``path`` imports (absolute imports), wherever in the file."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module)
    return names
