"""The front page stays a front page, and no link of it or of the docs site points nowhere (the
site's own strict build, run by ./scripts/test, checks the pages' links and docstrings)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
LINK = re.compile(r'!?\[[^\]]*\]\(([^)\s#]+)(?:#[^)]*)?\)')
PAGES = [ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md'))]


def test_the_readme_is_a_front_page():
    lines = (ROOT / 'README.md').read_text().splitlines()
    assert len(lines) <= 200, f'README.md has {len(lines)} lines: move text to docs/'
    first_screen = '\n'.join(lines[:30])
    assert '![' in first_screen, 'no picture on the first screen'
    assert './scripts/omni-micro demo' in first_screen and './scripts/test' in first_screen


@pytest.mark.parametrize('page', PAGES, ids=lambda page: page.name)
def test_every_relative_link_resolves(page):
    for target in LINK.findall(page.read_text()):
        if '://' in target or target.startswith('mailto:'):
            continue
        assert (page.parent / target).exists(), f'{page.name} links to missing {target}'


def test_every_docs_page_is_in_the_site_navigation():
    nav = (ROOT / 'mkdocs.yml').read_text()
    for page in (ROOT / 'docs').glob('*.md'):
        assert f': {page.name}' in nav, f'{page.name} is not in mkdocs.yml nav'
