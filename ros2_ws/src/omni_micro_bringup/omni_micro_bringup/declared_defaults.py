"""The graph's params file (config/omni_micro.yaml) against the code: every node's declared
parameters and their defaults, read from the nodes themselves, and the file's values rewritten
from them.

The file's values are the code's: ``scripts/params --write`` writes a default the code changed
into the file (its comments and layout stay), and ``tests/nodes/test_shipped_params.py`` fails
while they disagree or while a declared parameter is missing from it.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import math
import re
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omni_micro_bringup.params_files import format_parameter
from omni_micro_common.params import flatten, load_params_file

# Parameters a node declares that the file leaves to the command line, the bringup or another
# file: the bag to write (and a camera driver's images in it), who takes part in the lockstep,
# whose readers a node waits for (the bringup's composition sets them for each run), a
# fleet's robots (run --robots), a camera's calibration (what `omni-micro
# calibrate-camera` writes), and rclpy's own.
LEFT_TO_THE_RUN = {'bag_recorder': {'bag', 'topics', 'driver_images'},
                   'dynamics_node': {'lockstep_nodes', 'awaited_readers', 'robots',
                                     'robot_poses', 'robot_wheel_offsets_rad'},
                   'vision_node': {'capture_readers', 'covariance_readers', 'motion_readers',
                                   'status_readers'},
                   'tracker_node': {'capture_readers', 'covariance_readers', 'motion_readers',
                                    'robots'},
                   'camera_node': {'image_readers', 'robots'}, 'markers_node': {'markers_readers'},
                   'controller_node': {'trajectory_readers', 'status_readers'},
                   'omni_micro_viewer': {'robots'}}
LEFT_TO_ANOTHER_FILE = re.compile(r'^\w+\.calibration\.')
RCLPY_OWN = {'use_sim_time', 'start_type_description_service'}
# What a node needs to be built at all (the recorder a bag folder, the viewer a free port);
# their declared defaults are read all the same.
_TO_BUILD: dict[str, dict[str, Any]] = {'bag_recorder': {'bag': '{tmp}/bag'},
                                        'viewer': {'port': 0}}


@dataclass(frozen=True)
class Drift:
    node: str
    key: str
    in_file: object
    declared: object


def node_modules() -> dict[str, str]:
    """Each installed executable of the omni_micro packages that runs a node: its module, from
    the console_scripts that ``ros2 run`` starts."""
    modules = {}
    for entry in importlib.metadata.entry_points(group='console_scripts'):
        module = entry.value.partition(':')[0]
        if module.startswith('omni_micro_') and module.endswith('_node'):
            modules[entry.name] = module
    return modules


def declared_defaults(executable: str, module: str, context: Any) -> tuple[str, dict[str, Any]]:
    """The node ``module`` runs: its name and every parameter it declares, with the default it
    declares it with (dotted names), whatever it was built with."""
    component = importlib.import_module(module).COMPONENT
    recorded: dict[str, Any] = {}

    class Recording(component.factory):  # type: ignore[name-defined]
        def declare_parameter(self, name: str, value: Any = None, *args: Any,
                              **kwargs: Any) -> Any:
            recorded[name] = value
            return super().declare_parameter(name, value, *args, **kwargs)

    from rclpy.parameter import Parameter

    with tempfile.TemporaryDirectory() as tmp:
        given = [Parameter(key, value=value.format(tmp=tmp) if isinstance(value, str) else value)
                 for key, value in _TO_BUILD.get(executable, {}).items()]
        node = Recording(context=context, parameter_overrides=given)
        try:
            return node.get_name(), recorded
        finally:
            node.destroy_node()


def same(in_file: object, declared: object) -> bool:
    """Equal as ROS compares them, floats to 1e-12 (3 deg in radians, computed two ways,
    differs in its last bit)."""
    if isinstance(in_file, (list, tuple)) and isinstance(declared, (list, tuple)):
        return len(in_file) == len(declared) and all(
            same(a, b) for a, b in zip(in_file, declared, strict=True))
    if isinstance(in_file, float) or isinstance(declared, float):
        return (isinstance(in_file, (int, float)) and isinstance(declared, (int, float))
                and not isinstance(in_file, bool)
                and math.isclose(in_file, declared, rel_tol=1e-12, abs_tol=1e-15))
    return in_file == declared


def all_declared(context: Any) -> dict[str, dict[str, Any]]:
    """Every node's declared parameters, by node name."""
    nodes = {}
    for executable, module in sorted(node_modules().items()):
        name, declared = declared_defaults(executable, module, context)
        nodes[name] = declared
    return nodes


def drifts(path: Path, declared: dict[str, dict[str, Any]]) -> tuple[list[Drift], list[str]]:
    """Where the file's values differ from the code's, and what a node declares that the file
    lacks (``node: key``) or holds that no node declares."""
    sections = load_params_file(path)
    found: list[Drift] = []
    missing = []
    for node, defaults in declared.items():
        in_file = flatten(sections.get(node, {}))
        for key, value in in_file.items():
            if key not in defaults:
                missing.append(f'{node}: {key} (in the file, declared by no node)')
            elif not same(value, defaults[key]):
                found.append(Drift(node, key, value, defaults[key]))
        left = LEFT_TO_THE_RUN.get(node, set()) | RCLPY_OWN
        missing += [f'{node}: {key}' for key in defaults if key not in in_file
                    and key not in left and not LEFT_TO_ANOTHER_FILE.match(key)]
    missing += [f'{node} (a section of no node)' for node in sections if node not in declared]
    return found, missing


_LINE = re.compile(r'^(?P<indent> *)(?P<key>[\w.]+):(?P<gap> +)(?P<value>[^#\n]*?)'
                   r'(?P<rest> *(?:#.*)?)$')


def _keyed_lines(lines: list[str]) -> Iterator[tuple[int, str, str, re.Match[str]]]:
    """(line index, node, dotted key, match) of every ``key: value`` line of a params file."""
    stack: list[tuple[int, str]] = []
    for index, line in enumerate(lines):
        if not line.strip() or line.lstrip().startswith('#'):
            continue
        match = _LINE.match(line) or re.match(r'^(?P<indent> *)(?P<key>[\w.]+):\s*(#.*)?$', line)
        if match is None:
            continue
        depth = len(match.group('indent'))
        while stack and stack[-1][0] >= depth:
            stack.pop()
        path = [key for _, key in stack]
        if 'value' in match.groupdict() and match.group('value'):
            if len(path) >= 2 and path[1] == 'ros__parameters':
                yield index, path[0], '.'.join([*path[2:], match.group('key')]), match
        else:
            stack.append((depth, match.group('key')))


def yaml_value(value: object) -> str:
    """``value`` as the file writes it: as ``-p`` gives it (:func:`.parameters.format_parameter`),
    but a float always with its point (YAML 1.1 reads 3e-06 as a string), lists spaced, and an
    empty string quoted."""
    if isinstance(value, float) and math.isfinite(value):
        mantissa, e, exponent = repr(value).partition('e')
        return (mantissa if '.' in mantissa else f'{mantissa}.0') + (e + exponent if e else '')
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(yaml_value(item) for item in value) + ']'
    return "''" if value == '' else format_parameter(value)


def rewrite(text: str, found: list[Drift]) -> str:
    """``text`` with each drifted value replaced by the code's, its comment kept in place."""
    wanted = {(drift.node, drift.key): drift.declared for drift in found}
    lines = text.split('\n')
    for index, node, key, match in list(_keyed_lines(lines)):
        if (node, key) not in wanted:
            continue
        value = yaml_value(wanted[(node, key)])
        old = match.group('value')
        rest = match.group('rest')
        pad = max(1, len(old) - len(value) + (len(rest) - len(rest.lstrip())))
        lines[index] = (f'{match.group("indent")}{match.group("key")}:{match.group("gap")}{value}'
                        + ((' ' * pad + rest.lstrip()) if rest.strip() else ''))
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    """``scripts/params``: check the graph's params file against the code, or (``--write``)
    write the code's defaults into it."""
    import argparse
    import os
    import sys

    import rclpy
    from rclpy.context import Context

    parser = argparse.ArgumentParser(
        prog='scripts/params',
        description="Compare config/omni_micro.yaml of omni_micro_bringup with the defaults every "
                    "node declares (each node built in-process); with --write, put the code's "
                    'values into the file, its comments and layout kept. Exit 1 when they '
                    'differ (without --write) or when the file lacks a declared parameter.')
    parser.add_argument('--file', type=Path, required=True, help='the params file to check')
    parser.add_argument('--write', action='store_true', help="write the code's values")
    args = parser.parse_args(argv)
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    context = Context()
    # The nodes are built and destroyed without spinning: nothing they announce is read.
    rclpy.init(context=context, domain_id=int(os.environ.get('ROS_DOMAIN_ID', '0')))
    try:
        declared = all_declared(context)
    finally:
        rclpy.try_shutdown(context=context)
    found, missing = drifts(args.file, declared)
    for drift in found:
        print(f'{drift.node}: {drift.key} is {drift.in_file!r} in the file, {drift.declared!r} '
              'in the code', file=sys.stderr)
    for line in missing:
        print(f'not in the file: {line}', file=sys.stderr)
    if found and args.write:
        args.file.write_text(rewrite(args.file.read_text(), found))
        print(f'{args.file}: {len(found)} value(s) written from the code', file=sys.stderr)
        found = []
    if not found and not missing:
        print(f'{args.file}: every value is the code\'s', file=sys.stderr)
    return 1 if found or missing else 0


if __name__ == '__main__':
    raise SystemExit(main())
