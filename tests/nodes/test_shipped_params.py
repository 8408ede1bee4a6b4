"""The graph's params file says what the code does: every parameter a node declares is in it, at
the default the node declares (a file that drifted from the code would change a run started with
it from one started without, and nobody would see why). ``scripts/params --write`` mends one."""

from __future__ import annotations

from pathlib import Path

import pytest
from rclpy.parameter import Parameter

from omni_micro_bringup.declared_defaults import all_declared, drifts, node_modules, rewrite, same

GRAPH_PARAMS = (Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src' / 'omni_micro_bringup'
                / 'config' / 'omni_micro.yaml')


@pytest.fixture(scope='module')
def declared():
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    try:
        yield all_declared(context)
    finally:
        rclpy.try_shutdown(context=context)


def test_every_node_of_the_packages_is_read(declared):
    assert set(node_modules()) == {'dynamics_node', 'vision_node', 'camera_node', 'tracker_node',
                                   'markers_node', 'controller_node', 'bag_recorder', 'viewer'}
    assert set(declared) == {'dynamics_node', 'vision_node', 'camera_node', 'tracker_node',
                             'markers_node', 'controller_node', 'bag_recorder',
                             'omni_micro_viewer'}


def test_the_graph_params_file_holds_every_declared_parameter_at_its_default(declared):
    found, missing = drifts(GRAPH_PARAMS, declared)
    assert found == [], 'scripts/params --write puts the code\'s values in the file'
    assert missing == [], 'add these to config/omni_micro.yaml, with a comment'


def test_a_drifted_value_is_found_and_written_back_with_its_comment(declared, tmp_path):
    shipped = GRAPH_PARAMS.read_text()
    controller_tolerance = 'tolerance_m: 3.0e-6             #'
    drifted = (shipped.replace('      mu_transverse: 0.21\n', '      mu_transverse: 0.25\n', 1)
               .replace(controller_tolerance, 'tolerance_m: 4e-6               #', 1))
    assert drifted.count('0.25') > shipped.count('0.25')
    copy = tmp_path / 'drifted.yaml'
    copy.write_text(drifted)
    found, missing = drifts(copy, declared)
    assert {(d.node, d.key, d.in_file) for d in found} == {
        ('dynamics_node', 'robot.mu_transverse', 0.25), ('controller_node', 'tolerance_m', 4e-6)}
    assert missing == []
    mended = rewrite(drifted, found)
    assert '    tolerance_m: 3.0e-06            # reached when' in mended
    copy.write_text(mended)
    assert drifts(copy, declared) == ([], [])


def test_a_key_no_node_declares_is_named(declared, tmp_path):
    copy = tmp_path / 'extra.yaml'
    copy.write_text(GRAPH_PARAMS.read_text().replace('    odom_frame: odom\n',
                                                     '    odom_frame: odom\n    odom_fram: x\n'))
    assert 'dynamics_node: odom_fram (in the file, declared by no node)' in drifts(copy,
                                                                                declared)[1]


def test_a_drifted_value_is_caught():
    assert not same([0.0, 0.0523598775598, 0.0349065850398866], [0.0, 0.05236, 0.0349])
    assert not same(3, 3.5) and not same('paper', 'model') and same(3.0, 3)
    assert not same(True, 1.0)


def test_the_controllers_cruise_speed_is_the_motors_not_a_second_parameter(context):
    """Derived, not checked for agreement: one number, motor.cruise_speed_rad_s."""
    from omni_micro_control.controller_node import ControllerNode
    from omni_micro_control.feedback import VisionFeedbackController

    node = ControllerNode(context=context, parameter_overrides=[
        Parameter('motor.cruise_speed_rad_s', value=6.0)])
    try:
        assert not node.has_parameter('cruise_speed_rad_s')
        assert isinstance(node.controller, VisionFeedbackController)
        assert node.controller.config.cruise_speed_rad_s == 6.0
    finally:
        node.destroy_node()
