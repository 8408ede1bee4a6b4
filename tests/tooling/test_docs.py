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


def test_the_sites_front_page_is_the_readme():
    """docs/index.md was an older copy of the README (its demo table short of three rows, "33
    s"): it is now written from it by scripts/docs, and a copy edited by hand fails here."""
    import importlib.util

    spec = importlib.util.spec_from_file_location('front_page',
                                                  ROOT / 'scripts' / 'lib' / 'front_page.py')
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    readme = (ROOT / 'README.md').read_text()
    assert (ROOT / 'docs' / 'index.md').read_text() == module.front_page(readme), \
        'docs/index.md differs from the README: run ./scripts/docs (edit README.md, not it)'
    assert module.front_page('see [x](docs/a.md) and ![](docs/figures/b.png)').endswith(
        'see [x](a.md) and ![](figures/b.png)')


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
