"""The layout shows the architecture: no module grows past what one concern needs, and a topic's
name is written once. (Each package's docstring naming its modules: test_imports.py; no verb of
the command line built on another: tests/cli/test_verbs_apart.py.)"""

from __future__ import annotations

from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src'
# A module past this many lines holds more than one concern: split it by concern.
MAX_MODULE_LINES = 400


def test_no_module_is_over_the_line_limit():
    long = {str(path.relative_to(SRC)): lines for path in SRC.rglob('*.py')
            if (lines := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert long == {}, f'split these by concern (over {MAX_MODULE_LINES} lines): {long}'


def topic_literals(source: str) -> list[str]:
    """The string literals in ``source`` that are exactly a topic name of the graph."""
    import io
    import tokenize

    from omni_micro_common import topic_names

    names = {value for key, value in vars(topic_names).items() if key.endswith('_TOPIC')}
    names |= {topic for key, value in vars(topic_names).items() if key.endswith('_TOPICS')
              for topic in (value.values() if isinstance(value, dict) else value)}
    return [token.string for token in tokenize.generate_tokens(io.StringIO(source).readline)
            if token.type == tokenize.STRING and token.string[1:-1] in names
            and token.string[0] in '\'"']


def test_a_topic_name_is_written_once():
    """Every node and tool names a topic by its constant in omni_micro_common.topic_names."""
    written = {str(path.relative_to(SRC)): found for path in SRC.rglob('*.py')
               if path.name != 'topic_names.py'
               and (found := topic_literals(path.read_text()))}
    assert written == {}, f'use omni_micro_common.topic_names: {written}'


def test_the_topic_check_sees_a_literal_but_not_a_docstring():
    assert topic_literals("x = '/odom'\n") == ["'/odom'"]
    assert topic_literals('"""Reads /odom."""\nx = f"{a}/odom"\n') == []
