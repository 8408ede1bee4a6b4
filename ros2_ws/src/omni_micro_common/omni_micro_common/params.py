"""Params files (what ``--params-file`` takes): the one reader the nodes, the orchestration and
the command line share.

A params file is UTF-8 YAML mapping node names (``controller_node``, ``/controller_node``, or
``/**`` for every node) to ``{ros__parameters: {...}}``; nested keys are dotted parameter names.
"""

from __future__ import annotations

import copy
import functools
import re
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import yaml

from omni_micro_common.errors import ParamsFileError


class _RosLoader(getattr(yaml, 'CSafeLoader', yaml.SafeLoader)):  # type: ignore[misc]
    """YAML as ROS 2 reads a params file: ``3e0`` and ``1.0e300`` are numbers (YAML 1.2, and
    rcl's parser), where YAML 1.1 takes a float without a dot or an exponent's sign for a
    string. Parsed by libyaml where PyYAML has it (its wheels do): the pure-Python parser took a
    second of a run's start-up, reading the graph's params file for each node."""


_RosLoader.add_implicit_resolver(
    'tag:yaml.org,2002:float',
    re.compile(r'^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$'),
    list('-+0123456789.'))

# Sections that apply to every node.
WILDCARD_SECTIONS = ('/**', '**')


def read_yaml(path: Path | str) -> Any:
    """A params file's YAML content, not yet checked for shape (a copy: the caller may change
    it). The same unchanged file is parsed once a process.

    Raises
    ------
    ParamsFileError
        The file is missing or unreadable, not UTF-8 or not YAML.
    """
    where = f'params file {str(path)!r}'
    try:
        if not Path(path).is_file():
            raise ParamsFileError(f'{where} does not exist')
        stat = Path(path).stat()
    except OSError as error:
        raise ParamsFileError(f'{where} cannot be read: {error.strerror}') from None
    return copy.deepcopy(_parsed(str(path), stat.st_mtime_ns, stat.st_size))


@functools.lru_cache(maxsize=32)
def _parsed(path: str, mtime_ns: int, size: int) -> Any:
    """The YAML of ``path`` as it is at ``mtime_ns`` and ``size`` (they key the cache)."""
    where = f'params file {path!r}'
    try:
        text = Path(path).read_text(encoding='utf-8')
    except UnicodeDecodeError as error:
        raise ParamsFileError(f'{where} is not UTF-8 text (byte {error.start}): '
                              'expected a YAML file') from None
    except OSError as error:
        raise ParamsFileError(f'{where} cannot be read: {error.strerror}') from None
    try:
        content = yaml.load(text, Loader=_RosLoader)
    except yaml.YAMLError as error:
        raise ParamsFileError(f'{where} does not parse as YAML: {error}') from None
    return content


def load_params_file(path: Path | str) -> dict[str, dict[str, Any]]:
    """The sections of a params file, each its ``ros__parameters`` mapping (nested).

    Raises
    ------
    ParamsFileError
        The file is missing or unreadable, not UTF-8, not YAML, or not shaped as ROS 2 wants;
        the message names the file and what is wrong.
    """
    content = read_yaml(path)
    where = f'params file {str(path)!r}'
    if not isinstance(content, dict) or not all(
            isinstance(section, dict) and isinstance(section.get('ros__parameters'), dict)
            for section in content.values()):
        raise ParamsFileError(f'{where} must map node names to {{ros__parameters: {{...}}}}, '
                              f'got {content!r:.200}')
    return {str(name): body['ros__parameters'] for name, body in content.items()}


def flatten(values: Mapping[str, Any], prefix: str = '') -> dict[str, Any]:
    """Nested parameters as ROS 2 names them: ``{'a': {'b': 1}}`` -> ``{'a.b': 1}``."""
    flat: dict[str, Any] = {}
    for key, value in values.items():
        name = f'{prefix}{key}'
        if isinstance(value, dict):
            flat.update(flatten(value, f'{name}.'))
        else:
            flat[name] = value
    return flat


def node_parameters(paths: Iterable[Path | str], node: str) -> dict[str, Any]:
    """What ``node`` is given by ``paths`` in order (later files win), as dotted names.

    Within a file the node's own section is read before the wildcard section, as before.
    """
    values: dict[str, Any] = {}
    for path in paths:
        sections = load_params_file(path)
        for name in (node, f'/{node}', *WILDCARD_SECTIONS):
            values.update(flatten(sections.get(name, {})))
    return values
