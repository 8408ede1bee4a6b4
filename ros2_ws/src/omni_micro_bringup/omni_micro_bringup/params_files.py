"""Where the installed nodes and the graph's params file are, and what each node will be given."""

from __future__ import annotations

import difflib
import math
import os
from collections.abc import Sequence
from pathlib import Path

from omni_micro_bringup.errors import RunFailed
from omni_micro_common import params
from omni_micro_common.errors import ParamsFileError
from omni_micro_common.installed import dds_profile_file, install_prefixes


def resolve_executable(package: str, executable: str) -> Path:
    """Where ``ros2 run package executable`` would find it: <prefix>/lib/<package>/<exe>, or the
    venv's bin/ where pip puts console scripts."""
    for prefix in install_prefixes():
        for candidate in (prefix / 'lib' / package / executable, prefix / 'bin' / executable):
            if candidate.is_file() and os.access(candidate, os.X_OK):
                return candidate
    raise RunFailed(f'{package}/{executable} is not installed under '
                    f'{[str(p) for p in install_prefixes()]} (run ./scripts/test once to install)')


# The graph's params file (config/omni_micro.yaml of this package): a section per node.
GRAPH_PARAMS_FILE = 'omni_micro.yaml'


def graph_params_file() -> Path:
    """The installed params file of the graph, every node's section in it."""
    for prefix in install_prefixes():
        path = prefix / 'share' / 'omni_micro_bringup' / 'config' / GRAPH_PARAMS_FILE
        if path.is_file():
            return path
    raise RunFailed(f'params file config/{GRAPH_PARAMS_FILE} of omni_micro_bringup is not '
                    'installed')


def format_parameter(value: object) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return ('.inf' if value > 0 else '-.inf') if math.isinf(value) else repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(format_parameter(v) for v in value) + ']'
    text = str(value)
    if isinstance(value, str) and any(c in text for c in YAML_SPECIAL):
        # rcl reads -p values as YAML: 'node:/topic' unquoted in a list does not parse.
        return "'" + text.replace("'", "''") + "'"
    return text


# Characters that make a plain YAML scalar mean something else, or not parse.
YAML_SPECIAL = frozenset(':#,[]{}&*!|>\'"%@`')


def check_params_file(path: Path, nodes: Sequence[str] = ()) -> None:
    """Refuse a params file that would make a node die at start-up, or (with ``nodes``, those
    of the graph) that has a section for a node the graph does not have, which ROS would pass
    over in silence: say what is wrong with it.

    Raises
    ------
    omni_micro_common.errors.ParamsFileError
        Naming the file and what is wrong with it.
    """
    sections = params.load_params_file(path)
    for section in sections if nodes else ():
        bare = section.lstrip('/')
        if section not in params.WILDCARD_SECTIONS and bare not in nodes:
            close = difflib.get_close_matches(bare, nodes, n=1, cutoff=0.6)
            raise ParamsFileError(
                f'params file {str(path)!r}: section {section!r} names no node of the graph '
                f'{list(nodes)}' + (f' (did you mean {close[0]!r}?)' if close else ''))


def dds_profile() -> Path:
    """The Fast DDS profile of the graph's processes (installed with omni_micro_common)."""
    path = dds_profile_file()
    if path is not None:
        return path
    raise RunFailed('config/fastdds.xml of omni_micro_common is not installed')


def node_parameters(node: str, params_files: tuple[Path, ...],
                    overrides: dict[str, object]) -> dict[str, object]:
    """A node's parameters as it will have them: the graph's file, the user's --params files
    in turn, then the orchestration's overrides (dotted names, as -p gives them)."""
    values = params_from_files(node, *params_files)
    values.update(overrides)
    return values


def params_from_files(node: str, *params_files: Path | None) -> dict[str, object]:
    """A node's parameters from the graph's file, then each of ``params_files`` in turn
    (dotted names; None stands for no file)."""
    files = [graph_params_file(),
             *(path for path in params_files if path is not None)]
    return params.node_parameters(files, node)
