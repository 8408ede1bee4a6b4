"""What rclpy would pass over in silence when a node starts: a parameter it does not declare, a
value of another type, a params file that does not parse; each refused in one line."""

from __future__ import annotations

import difflib
import itertools
from typing import Any

import yaml
from rclpy.node import Node
from rclpy.parameter import Parameter

from omni_micro_common.errors import ParameterError
from omni_micro_common.params import WILDCARD_SECTIONS, flatten, read_yaml


def params_files(argv: list[str]) -> list[str]:
    """The --params-file paths of a ROS command line, in order."""
    files = []
    for flag, value in itertools.pairwise(argv):
        if flag == '--params-file':
            files.append(value)
    return files


def _suggestion(word: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
    return f' (did you mean {close[0]!r}?)' if close else ''


def check_given_parameters(node: Node, argv: list[str]) -> None:
    """Refuse what rclpy would pass over in silence: a key this node does not declare (from a
    params file or -p), a value of another type. (Sections for other nodes are theirs: the
    bringup, which knows the graph, refuses one that names no node of it.)

    Raises
    ------
    ParameterError
        Naming the file (or -p), the node, the key, the value and what was expected.
    """
    name = node.get_name()
    wildcard_keys: set[str] = set()
    origin: dict[str, str] = {}     # key -> the params file that gave it to this node
    own: dict[str, Any] = {}
    for path in params_files(argv):
        content = read_yaml(path) or {}
        if not isinstance(content, dict):
            raise ParameterError(f'params file {path!r} must map node names to '
                                 f'{{ros__parameters: ...}}, got {content!r:.100}')
        for section, body in content.items():
            bare = str(section).lstrip('/')
            if not isinstance(body, dict) or not isinstance(body.get('ros__parameters'), dict):
                raise ParameterError(f'params file {path!r}: section {section!r} must hold '
                                     f'ros__parameters: {{...}}, got {body!r:.100}')
            keys = flatten(body['ros__parameters'])
            if section in WILDCARD_SECTIONS:
                wildcard_keys.update(keys)
            elif bare == name:
                origin.update(dict.fromkeys(keys, path))
                own.update(keys)
            for key, value in keys.items():
                if bare == name or (section in WILDCARD_SECTIONS and node.has_parameter(key)):
                    _check_type(node, key, value, f'params file {path!r}')
    given = {key: (value, f'params file {origin[key]!r}') for key, value in own.items()}
    given.update({key: (value, 'given with -p') for key, value in command_line_parameters(
        argv, name).items()})
    declared = sorted(node.get_parameters_by_prefix(''))
    for key, (value, where) in given.items():
        if key in declared or key in wildcard_keys:
            continue
        raise ParameterError(
            f'{where}, node {name!r}: unknown parameter {key!r} = {value!r}'
            f'{_suggestion(key, declared)}; {name} declares: {", ".join(declared)}')


def command_line_parameters(argv: list[str], node_name: str) -> dict[str, Any]:
    """The ``-p NAME:=VALUE`` (or ``--param``, or ``-p NODE:NAME:=VALUE`` for this node) of the
    ROS arguments in ``argv``, each value read as YAML, as rcl reads it."""
    given: dict[str, Any] = {}
    for flag, assignment in itertools.pairwise(argv):
        if flag not in ('-p', '--param') or ':=' not in assignment:
            continue
        name, _, text = assignment.partition(':=')
        node, _, key = name.rpartition(':')
        if node and node.lstrip('/') != node_name:
            continue
        try:
            given[key] = yaml.safe_load(text)
        except yaml.YAMLError:
            given[key] = text
    return given


_TYPE_NAMES = {Parameter.Type.BOOL: 'true or false', Parameter.Type.INTEGER: 'a whole number',
               Parameter.Type.DOUBLE: 'a number with a decimal point (e.g. 5.0)',
               Parameter.Type.STRING: 'a string',
               Parameter.Type.BOOL_ARRAY: 'a list of true/false',
               Parameter.Type.INTEGER_ARRAY: 'a list of whole numbers',
               Parameter.Type.DOUBLE_ARRAY: 'a list of numbers with decimal points',
               Parameter.Type.STRING_ARRAY: 'a list of strings'}


def _check_type(node: Node, key: str, value: Any, where: str) -> None:
    """A value whose type differs from the declared one: rclpy refuses it from a single file,
    but from a second file rcl drops it without a word, so check it here for both."""
    if not node.has_parameter(key):
        return
    expected = node.get_parameter(key).type_
    if expected == Parameter.Type.NOT_SET:
        return
    if isinstance(value, list) and not value and expected in (
            Parameter.Type.BOOL_ARRAY, Parameter.Type.INTEGER_ARRAY,
            Parameter.Type.DOUBLE_ARRAY, Parameter.Type.STRING_ARRAY):
        return   # [] has no element type: any array type takes it
    try:
        given = Parameter.Type.from_parameter_value(value)
    except TypeError:
        given = None
    if given != expected:
        raise ParameterError(
            f'{where}, node {node.get_name()!r}: parameter {key!r} = {value!r} has the wrong '
            f'type: expected {_TYPE_NAMES.get(expected, expected.name)}')
