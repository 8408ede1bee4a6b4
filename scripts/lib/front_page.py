"""The docs site's front page is the README: docs/index.md is written from it, its paths made
relative to docs/ (scripts/docs does this before every build; tests/tooling/test_docs.py fails
when the committed copy differs). One front page, never two that drift apart."""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HEADER = ('<!-- Written from README.md by scripts/docs (scripts/lib/front_page.py): edit the '
          'README. -->\n')


def front_page(readme: str) -> str:
    """The README as docs/index.md reads it: links and figures relative to docs/."""
    return HEADER + readme.replace('](docs/', '](').replace('docs/figures/', 'figures/')


def main() -> int:
    target = ROOT / 'docs' / 'index.md'
    text = front_page((ROOT / 'README.md').read_text(encoding='utf-8'))
    if not target.exists() or target.read_text(encoding='utf-8') != text:
        target.write_text(text, encoding='utf-8')
    return 0


if __name__ == '__main__':
    sys.exit(main())
