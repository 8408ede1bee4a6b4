"""A newcomer's parameter mistakes get exit 2 and a message that names them, never a run that
quietly used the defaults: misspelt keys and node sections, wrong types, with --params, with a
node started alone, and with -p."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from omni_micro_bringup.params_files import graph_params_file, resolve_executable
from omni_micro_bringup.processes import node_environment

PACKAGES = {'dynamics_node': 'omni_micro_sim', 'vision_node': 'omni_micro_vision',
            'controller_node': 'omni_micro_control'}


def params(tmp_path: Path, text: str) -> Path:
    path = tmp_path / 'mine.yaml'
    path.write_text(text)
    return path


@pytest.mark.parametrize('text, expected', [
    ('controller_node:\n  ros__parameters:\n    tolerance_um: 5.0\n',
     ["node 'controller_node'", "unknown parameter 'tolerance_um' = 5.0",
      "did you mean 'tolerance_m'?"]),
    # Refused by the bringup, which knows the graph's nodes, before any starts.
    ('controler_node:\n  ros__parameters:\n    tolerance_m: 5.0e-6\n',
     ["section 'controler_node' names no node of the graph", "did you mean 'controller_node'?"]),
    ('controller_node:\n  ros__parameters:\n    tolerance_m: "five"\n',
     ["parameter 'tolerance_m' = 'five' has the wrong type",
      'expected a number with a decimal point']),
    ('dynamics_node:\n  ros__parameters:\n    robot:\n      mass_g: 2.8\n',
     ["unknown parameter 'robot.mass_g'", "did you mean 'robot.mass_kg'?"]),
    # Round 3: it was markers_node (given the value too) that refused it, and was named.
    ('controller_node:\n  ros__parameters:\n    tolerance_m: 5\n',
     ['controller_node refused its parameters', "'tolerance_m' to '5' of type 'INTEGER'"]),
])
def test_run_refuses_a_params_file_mistake_before_anything_moves(text, expected, tmp_path,
                                                                  omni_micro):
    path = params(tmp_path, text)
    result = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--params', str(path),
                        '--log-dir', str(tmp_path / 'logs'))
    assert result.returncode == 2, result.stderr[-2000:]
    assert str(path) in result.stderr
    assert 'names no node' in result.stderr or 'refused its parameters' in result.stderr
    for words in expected:
        assert words in result.stderr, result.stderr[-2000:]
    # Nothing moved: the robot's clock never ran and no move was commanded.
    logs = ''.join(log.read_text() for log in (tmp_path / 'logs').rglob('*.log'))
    assert 'period 1 (' not in logs and '"/clock"' not in logs


@pytest.mark.parametrize('node', list(PACKAGES))
def test_a_node_alone_refuses_a_misspelt_key_in_its_params_file_and_from_p(node, tmp_path,
                                                                            domain_id):
    own = graph_params_file()
    mine = params(tmp_path, f'{node}:\n  ros__parameters:\n    sed: 3\n')
    base = [str(resolve_executable(PACKAGES[node], node)), '--ros-args', '--params-file',
            str(own)]
    env = node_environment(domain_id, tmp_path)
    from_file = subprocess.run([*base, '--params-file', str(mine)], env=env, timeout=60,
                               capture_output=True, text=True)
    assert from_file.returncode == 2
    assert f"params file '{mine}', node '{node}': unknown parameter 'sed' = 3" in from_file.stdout
    from_p = subprocess.run([*base, '-p', 'sed:=3'], env=env, timeout=60, capture_output=True,
                            text=True)
    assert from_p.returncode == 2
    assert f"given with -p, node '{node}': unknown parameter 'sed' = 3" in from_p.stdout


def test_a_wildcard_section_may_hold_what_any_node_declares(tmp_path, omni_micro):
    """'/**' applies to every node: a key only one of them declares is not a mistake there."""
    path = params(tmp_path, '/**:\n  ros__parameters:\n    seed: 2\n')
    result = omni_micro('run', '--goal-mm', '100.5,0.3', '--rtf', 'max', '--params', str(path),
                        '--log-dir', str(tmp_path / 'logs'), '--quiet')
    assert result.returncode == 0, result.stderr[-2000:]


@pytest.mark.parametrize(('args', 'line'), [
    (['--params-file', 'MISSING'], "tracker_node: invalid parameter: params file 'MISSING' does "
                                   'not exist'),
    (['--params-file', 'LIST'], "tracker_node: invalid parameter: params file 'LIST' must map "
                                'node names to {ros__parameters: {...}}, got [1, 2]'),
    (['-p', 'cameras:=[]'], "tracker_node: invalid parameter: cameras must name at least one of "
                            "['macro', 'micro']"),
    (['-p', 'micro.image_topic:=not_a_topic!'],
     "tracker_node: invalid parameter: micro.image_topic: Invalid topic name: topic name must "
     "not contain characters other than alphanumerics, '_', '~', '{', or '}': 'not_a_topic!'"),
], ids=['missing-file', 'yaml-list', 'empty-cameras', 'bad-topic'])
def test_a_node_alone_refuses_what_rcl_or_rclpy_would_raise_in_one_line(args, line, tmp_path,
                                                                        domain_id):
    """Round 3: these were an RCLError, a TypeError and an InvalidTopicNameException traceback
    from the node started alone."""
    listed = params(tmp_path, '[1, 2]\n')
    argv = [a.replace('MISSING', str(tmp_path / 'none.yaml')).replace('LIST', str(listed))
            for a in args]
    done = subprocess.run([str(resolve_executable('omni_micro_vision', 'tracker_node')),
                           '--ros-args', *argv], env=node_environment(domain_id, tmp_path),
                          timeout=60, capture_output=True, text=True)
    assert done.returncode == 2
    expected = line.replace('MISSING', str(tmp_path / 'none.yaml')).replace('LIST', str(listed))
    assert done.stdout.strip().splitlines()[-1] == expected
    assert 'Traceback' not in done.stdout + done.stderr
