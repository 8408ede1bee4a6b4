"""The graph's params file says what the code does: every value in it is the
default the node declares (a file that drifted from the code would change a run started with
it from one started without, and nobody would see why)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from rclpy.parameter import Parameter

from omni_micro_common.params import flatten, load_params_file

GRAPH_PARAMS = (Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src' / 'omni_micro_bringup'
                / 'config' / 'omni_micro.yaml')
# Each node with a shipped params file, and how to build it in-process.
NODES = {
    'dynamics_node': ('omni_micro_sim', 'omni_micro_sim.dynamics_node', 'DynamicsNode'),
    'vision_node': ('omni_micro_vision', 'omni_micro_vision.vision_node', 'VisionNode'),
    'camera_node': ('omni_micro_vision', 'omni_micro_vision.camera_node', 'CameraNode'),
    'tracker_node': ('omni_micro_vision', 'omni_micro_vision.tracker_node', 'TrackerNode'),
    'markers_node': ('omni_micro_vision', 'omni_micro_vision.markers_node', 'MarkersNode'),
    'controller_node': ('omni_micro_control', 'omni_micro_control.controller_node',
                        'ControllerNode'),
    'bag_recorder': ('omni_micro_tools', 'omni_micro_tools.recorder_node', 'BagRecorder'),
}
# The viewer binds its port when made (its file: host, port, markers): not built here.
NOT_BUILT = {'omni_micro_viewer'}


def same(shipped: object, declared: object) -> bool:
    """Equal as ROS compares them, floats to 1e-12 (3 deg in radians, computed two ways,
    differs in its last bit)."""
    if isinstance(shipped, (list, tuple)) and isinstance(declared, (list, tuple)):
        return len(shipped) == len(declared) and all(
            same(a, b) for a, b in zip(shipped, declared, strict=True))
    if isinstance(shipped, float) or isinstance(declared, float):
        return (isinstance(shipped, (int, float)) and isinstance(declared, (int, float))
                and math.isclose(shipped, declared, rel_tol=1e-12, abs_tol=1e-15))
    return shipped == declared


def test_every_section_of_the_graph_params_file_is_checked_here():
    shipped = set(load_params_file(GRAPH_PARAMS))
    assert shipped - NOT_BUILT == set(NODES)


@pytest.mark.parametrize('name', list(NODES))
def test_a_shipped_params_file_holds_the_defaults_the_node_declares(name, context, tmp_path):
    import importlib

    from rclpy.parameter import Parameter

    _, module, cls = NODES[name]
    # The recorder needs a bag to make (its file leaves that to the command line).
    given = [Parameter('bag', value=str(tmp_path / 'bag'))] if name == 'bag_recorder' else []
    node = getattr(importlib.import_module(module), cls)(context=context,
                                                         parameter_overrides=given)
    try:
        shipped = flatten(load_params_file(GRAPH_PARAMS)[name])
        differ = {key: (value, node.get_parameter(key).value)
                  for key, value in shipped.items()
                  if not node.has_parameter(key) or
                  not same(value, node.get_parameter(key).value)}
        assert differ == {}, f'{name}: params file value, then the code\'s default: {differ}'
    finally:
        node.destroy_node()


def test_a_drifted_value_is_caught():
    assert not same([0.0, 0.0523598775598, 0.0349065850398866], [0.0, 0.05236, 0.0349])
    assert not same(3, 3.5) and not same('paper', 'model') and same(3.0, 3)


def test_the_controllers_cruise_speed_is_the_motors_not_a_second_parameter(context):
    """Derived, not checked for agreement: one number, motor.cruise_speed_rad_s."""
    from omni_micro_control.controller_node import ControllerNode

    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('motor.cruise_speed_rad_s', value=6.0)])
    try:
        assert not node.has_parameter('cruise_speed_rad_s')
        assert node.controller.config.cruise_speed_rad_s == 6.0
    finally:
        node.destroy_node()
