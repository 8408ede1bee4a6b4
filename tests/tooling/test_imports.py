"""What each entry point loads: the nodes a real camera set-up runs load no physics, and the
shared contracts load nothing but ROS and YAML (the command line's help: tests/cli/test_help.py).

Checked in a fresh interpreter each (an import, unlike a time, does not flake)."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from import_probe import loaded_after

ROOT = Path(__file__).resolve().parents[2]

PHYSICS = ('numba', 'llvmlite', 'scipy')


@pytest.mark.parametrize(('module', 'node', 'overrides'), [
    ('omni_micro_vision.tracker_node', 'TrackerNode', {}),
    ('omni_micro_vision.vision_node', 'VisionNode', {}),
    ('omni_micro_vision.markers_node', 'MarkersNode', {}),
    ('omni_micro_control.controller_node', 'ControllerNode', {'mode': 'paper'}),
])
def test_nodes_of_a_camera_set_up_start_without_the_physics(module, node, overrides):
    code = node_start(module, node, overrides)
    assert loaded_after(code, PHYSICS) == []


def test_the_recorder_starts_without_the_physics(tmp_path):
    code = node_start('omni_micro_tools.recorder_node', 'BagRecorder',
                      {'bag': str(tmp_path / 'bag')})
    assert loaded_after(code, PHYSICS) == []


def node_start(module: str, node: str, overrides: dict[str, object]) -> str:
    return (f'import rclpy\nfrom rclpy.parameter import Parameter\nfrom {module} import {node}\n'
            'rclpy.init()\n'
            f'built = {node}(parameter_overrides=[Parameter(k, value=v) for k, v in '
            f'{overrides!r}.items()])\n'
            'built.destroy_node()\nrclpy.shutdown()')


def test_the_model_mode_loads_the_slip_core_when_it_first_predicts():
    """The control is real: the same probe sees numba once a prediction is made."""
    code = ('from omni_micro_control.chains import RecordedMove\n'
            'from omni_micro_control.identification import displacement\n'
            'from omni_micro_sim.parameters import RobotParameters\n'
            'from omni_micro_sim.profile import move_profile\n'
            'displacement(RobotParameters(), RecordedMove(0.0, move_profile(0.1)))')
    assert 'numba' in loaded_after(code, PHYSICS)


def test_the_shared_contracts_load_no_sibling_package():
    code = ('import omni_micro_common.conventions, omni_micro_common.qos, '
            'omni_micro_common.lockstep, omni_micro_common.node_runtime, '
            'omni_micro_common.params, omni_micro_common.messages')
    assert loaded_after(code, ('omni_micro_sim', 'omni_micro_vision', 'omni_micro_control',
                               'omni_micro_tools', 'omni_micro_bringup', 'omni_micro_cli',
                               *PHYSICS, 'numpy')) == []


@pytest.mark.parametrize('package', sorted(path.parent.name for path in
                                           (ROOT / 'ros2_ws' / 'src').glob('*/*/__init__.py')))
def test_every_module_is_named_in_its_packages_docstring(package):
    """Each package's __init__ says what its modules are (the convention the packages keep):
    ten were left out, so the docstring no longer showed the package."""
    folder = next((ROOT / 'ros2_ws' / 'src').glob(f'*/{package}'))
    docstring = ast.get_docstring(ast.parse((folder / '__init__.py').read_text())) or ''
    unnamed = [path.stem for path in sorted(folder.glob('*.py'))
               if path.stem not in ('__init__', '__main__')
               and f':mod:`{path.stem}`' not in docstring and f'``{path.stem}``' not in docstring]
    assert unnamed == [], f'{package}/__init__.py does not name {unnamed}'


def test_the_shared_contracts_name_no_node_of_the_graph():
    """Which nodes make the graph, and what each reads, is the bringup's to know: a node added
    to the graph (a user's own, a second robot's) touches omni_micro_bringup alone."""
    import ast

    from omni_micro_bringup.composition import GRAPH_NODE_NAMES, OPTIONAL_NODE_NAMES

    names = {*GRAPH_NODE_NAMES, *OPTIONAL_NODE_NAMES}
    common = ROOT / 'ros2_ws' / 'src' / 'omni_micro_common' / 'omni_micro_common'
    named = sorted(f'{path.name}: {node.value!r}' for path in common.glob('*.py')
                   for node in ast.walk(ast.parse(path.read_text()))
                   if isinstance(node, ast.Constant) and node.value in names)
    assert named == []
