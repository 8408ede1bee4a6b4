"""The docs' examples, as a newcomer copies them: the ``omni-micro`` command lines of every page
and the files a page shows."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

DOCS = Path(__file__).resolve().parents[2] / 'docs'
PAGES = [*sorted(DOCS.glob('*.md')), DOCS.parent / 'README.md']
SHELL_OPERATORS = ('|', '||', '&&', ';', '&')


def documented_command_lines(text: str) -> list[list[str]]:
    """The arguments of every ``omni-micro`` (or ``./scripts/omni-micro``) command in the
    shell blocks of a page, continuation lines joined, up to a pipe, a redirection or a
    comment. Optional parts written ``[--flag value]`` are taken as given, a placeholder
    ``N`` as 7; a line eliding its arguments (``...``) is left out."""
    lines = []
    for block in re.findall(r'```(?:bash|sh|console)\n(.*?)```', text, re.S):
        for line in block.replace('\\\n', ' ').splitlines():
            words = shlex.split(line.strip().removeprefix('$ '), comments=True)
            for start, word in enumerate(words):
                if word == 'omni-micro' or word.endswith('/omni-micro'):
                    argv = []
                    for word in words[start + 1:]:
                        if word in SHELL_OPERATORS or word.startswith(('>', '2>')):
                            break
                        argv.append('7' if word == 'N' else word.strip('[]'))
                    if '...' not in argv:
                        lines.append(argv)
    return lines


def documented_file(page: Path, name: str) -> str:
    """The YAML block of ``page`` whose first line is ``# <name>``."""
    for block in re.findall(r'```yaml\n(.*?)```', page.read_text(), re.S):
        if block.startswith(f'# {name}'):
            return block
    raise AssertionError(f'{page.name} shows no {name}')
