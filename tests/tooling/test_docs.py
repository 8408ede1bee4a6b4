"""The front page stays a front page, no link of it or of the docs site points nowhere (the
site's own strict build, run by ./scripts/test, checks the pages' links and docstrings), and the
development page's map of the packages names every module."""

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


def unmapped_modules(layout: str, src: Path) -> list[str]:
    """The packages' modules that ``layout`` (the map) does not name: by file or module name,
    but a verb of the command line's ``commands/`` (named there as one module per verb)."""
    verbs_mapped = 'commands/ (one module per verb' in layout
    return [str(path.relative_to(src)) for path in sorted(src.glob('*/*/**/*.py'))
            if path.stem not in ('__init__', '__main__')
            and not re.search(rf'\b{path.stem}\b', layout)
            and not (path.parent.name == 'commands' and verbs_mapped)]


def test_the_layout_names_every_module():
    """docs/development.md's map is how a newcomer finds a module: one added without a line
    there (targets.py was) leaves the map false."""
    page = (ROOT / 'docs' / 'development.md').read_text()
    layout = page.split('## Layout', 1)[1].split('\n## ', 1)[0]
    assert unmapped_modules(layout, ROOT / 'ros2_ws' / 'src') == []


def test_the_layout_check_sees_a_module_left_out(tmp_path):
    (tmp_path / 'pkg' / 'pkg').mkdir(parents=True)
    for name in ('__init__', 'named', 'forgotten'):
        (tmp_path / 'pkg' / 'pkg' / f'{name}.py').write_text('')
    assert unmapped_modules('pkg/  named.py (what it holds)', tmp_path) == [
        'pkg/pkg/forgotten.py']
