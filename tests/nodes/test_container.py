"""The container (several nodes in one process) and the graph's --composed layout: its command
line, which nodes it hosts and what each is told."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import pytest

from omni_micro_bringup.composition import MARKERS_NODE, all_specs
from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.node_overrides import node_overrides
from omni_micro_bringup.node_spec import LOOP_CONTAINER, NodeSpec, composed
from omni_micro_common.container import ContainerUsageError, load_component, parse_hosted
from omni_micro_common.node_runtime import NodeComponent

GRAPH_NODE_MODULES = ('omni_micro_sim.dynamics_node', 'omni_micro_vision.vision_node',
                      'omni_micro_vision.camera_node', 'omni_micro_vision.tracker_node',
                      'omni_micro_vision.markers_node', 'omni_micro_control.controller_node',
                      'omni_micro_tools.recorder_node', 'omni_micro_tools.viewer_node')


def test_each_node_module_takes_its_own_ros_arguments_up_to_the_separator():
    assert parse_hosted(['omni_micro_sim.dynamics_node', '--ros-args', '-p', 'paused:=true',
                         '--', 'omni_micro_vision.vision_node', '--ros-args', '--params-file',
                         'v.yaml', '--', 'omni_micro_control.controller_node']) == [
        ('omni_micro_sim.dynamics_node', ['--ros-args', '-p', 'paused:=true']),
        ('omni_micro_vision.vision_node', ['--ros-args', '--params-file', 'v.yaml']),
        ('omni_micro_control.controller_node', [])]


@pytest.mark.parametrize('argv, message', [
    ([], 'no node to run'),
    (['--ros-args', '-p', 'a:=1'], "expected a node module .* got '--ros-args'"),
    (['omni_micro_sim.dynamics_node', '-p', 'a:=1'], "got '-p'"),
])
def test_a_command_line_that_names_no_node_is_refused(argv, message):
    with pytest.raises(ContainerUsageError, match=message):
        parse_hosted(argv)


@pytest.mark.parametrize('module', GRAPH_NODE_MODULES)
def test_every_node_module_has_a_component(module):
    assert isinstance(load_component(module), NodeComponent)


@pytest.mark.parametrize('module, message', [
    ('omni_micro_sim.no_such_node', "no module 'omni_micro_sim.no_such_node' is installed"),
    ('omni_micro_common.qos', "'omni_micro_common.qos' has no COMPONENT"),
])
def test_what_is_not_a_node_module_is_named(module, message):
    with pytest.raises(ContainerUsageError, match=message):
        load_component(module)


@pytest.mark.slow
def test_the_container_refuses_bad_input_in_one_line_and_starts_nothing():
    env = {**os.environ, 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST'}
    bad = subprocess.run([sys.executable, '-m', 'omni_micro_common.container',
                          'omni_micro_sim.nope'], capture_output=True, text=True, env=env,
                         timeout=60)
    assert bad.returncode == 2 and 'Traceback' not in bad.stderr
    assert bad.stderr.startswith("container: no module 'omni_micro_sim.nope' is installed")
    refused = subprocess.run(
        [sys.executable, '-m', 'omni_micro_common.container', 'omni_micro_vision.vision_node',
         '--ros-args', '-p', 'seed:=-1'], capture_output=True, text=True, env=env, timeout=60)
    assert refused.returncode == 2 and 'Traceback' not in refused.stderr + refused.stdout
    assert 'omni_micro_vision.vision_node: invalid parameter: seed must be a whole number' \
        in refused.stdout
    # Two nodes of one name: rcl only warned, and each answered the other's parameters.
    twice = subprocess.run(
        [sys.executable, '-m', 'omni_micro_common.container', 'omni_micro_sim.dynamics_node',
         'omni_micro_sim.dynamics_node'], capture_output=True, text=True, env=env, timeout=60)
    assert twice.returncode == 2 and 'Traceback' not in twice.stderr + twice.stdout
    assert twice.stdout.strip().splitlines()[-1].endswith(
        ': invalid parameter: two nodes named /dynamics_node in one process: give one another '
        'name (--ros-args -r __node:=NAME --)')


def test_composed_the_loop_is_one_container_process_and_keeps_its_lockstep():
    options = GraphOptions(goal_m=(0.1, 0.0), real_time_factor=math.inf, composed=True,
                           markers=True)
    specs = all_specs(options)
    # A single robot's markers_node beside the container (a fleet's are hosted: test_one_graph).
    assert [spec.name for spec in specs] == [LOOP_CONTAINER, 'markers_node']
    loop = specs[0]
    assert (loop.package, loop.executable) == ('omni_micro_common', 'container')
    assert [spec.name for spec in loop.hosts] == ['dynamics_node', 'vision_node',
                                                  'controller_node']
    # The dynamics waits for the same reports as with separate processes, the markers' too.
    assert node_overrides(loop.hosts[0], options)['lockstep_nodes'] == [
        'vision_node', 'controller_node', 'markers_node']
    images = all_specs(GraphOptions(goal_m=(0.1, 0.0), composed=True, markers=False,
                                    vision='images'))
    assert [spec.name for spec in images[0].hosts] == [
        'dynamics_node', 'camera_node', 'tracker_node', 'controller_node']


def robot_nodes(count: int) -> list[NodeSpec]:
    return [NodeSpec('omni_micro_vision' if node == 'vision_node' else 'omni_micro_control',
                     node, namespace=f'robot_{k}')
            for k in range(count) for node in ('vision_node', 'controller_node')]


def test_composed_in_several_containers_the_dynamics_has_one_and_each_robot_stays_whole(
        monkeypatch):
    """The simulation's nodes in the first container; the robots' in contiguous blocks over
    the others, a robot's two nodes always together; the same nodes, each once, whatever the
    count; never a container with nothing to host."""
    dynamics = NodeSpec('omni_micro_sim', 'dynamics_node')
    specs = [dynamics, *robot_nodes(5)]
    three = composed(specs, 3)
    assert [spec.name for spec in three] == [LOOP_CONTAINER, f'{LOOP_CONTAINER}_1',
                                             f'{LOOP_CONTAINER}_2']
    assert [[hosted.name for hosted in spec.hosts] for spec in three] == [
        ['dynamics_node'],
        ['robot_0.vision_node', 'robot_0.controller_node', 'robot_1.vision_node',
         'robot_1.controller_node'],
        ['robot_2.vision_node', 'robot_2.controller_node', 'robot_3.vision_node',
         'robot_3.controller_node', 'robot_4.vision_node', 'robot_4.controller_node']]
    assert [len(spec.hosts) for spec in composed(specs, 9)] == [1, 2, 2, 2, 2, 2]
    assert [hosted for spec in composed(specs, 4) for hosted in spec.hosts] == specs
    assert [spec.hosts for spec in composed(specs, 1)] == [tuple(specs)]
    # Not said: one per core for two robots or more, one for a single robot's nodes.
    monkeypatch.setattr(os, 'sched_getaffinity', lambda pid: {0, 1})
    assert len(composed(specs)) == 2
    assert len(composed([dynamics, *robot_nodes(1)])) == 1
    single = all_specs(GraphOptions(goal_m=(0.1, 0.0), composed=True, markers=False))
    assert [spec.name for spec in single] == [LOOP_CONTAINER]
    with pytest.raises(UsageError, match='expected 1 container or more, got 0'):
        composed(specs, 0)


def test_the_clock_waits_for_the_readers_of_whoever_reports_draws_or_keeps_the_run():
    # The orchestration's too: the run's final pose is its odometry sample at the outcome.
    dynamics = NodeSpec('omni_micro_sim', 'dynamics_node')
    recorded = GraphOptions(goal_m=(0.1, 0.0), record=Path('bag'))
    assert node_overrides(dynamics, recorded)['awaited_readers'] == [
        'vision_node:/odom', 'controller_node:/joint_states', 'markers_node:/odom_throttle',
        'markers_node:/joint_states_throttle', 'markers_node:/wheel_slip',
        'bag_recorder:/clock', 'bag_recorder:/odom', 'bag_recorder:/joint_states',
        'bag_recorder:/wheel_slip', 'omni_micro_orchestration:/odom_throttle']
    bare = GraphOptions(goal_m=(0.1, 0.0), markers=False)
    assert node_overrides(dynamics, bare)['awaited_readers'] == [
        'vision_node:/odom', 'controller_node:/joint_states',
        'omni_micro_orchestration:/odom_throttle']
    # Composed: the hosted nodes' readers, all the same.
    following = GraphOptions(goal_m=(0.1, 0.0), markers=False, follow_route=True)
    awaited = node_overrides(dynamics, following)['awaited_readers']
    assert isinstance(awaited, list) and awaited[-1] == 'omni_micro_orchestration:/odom'
    composed = GraphOptions(goal_m=(0.1, 0.0), composed=True, markers=False)
    assert node_overrides(dynamics, composed)['awaited_readers'] == [
        'vision_node:/odom', 'controller_node:/joint_states',
        'omni_micro_orchestration:/odom_throttle']


def test_the_final_pose_is_the_sample_at_the_capture_or_a_clear_failure():
    from collections import deque

    from omni_micro_bringup.errors import RunFailed
    from omni_micro_bringup.orchestrator import first_sample_at_or_after

    creeping = deque(((0.02 * tick, 0.1 + 1e-14 * tick, 0.0, 0.0) for tick in range(10)),
                     maxlen=20)
    assert first_sample_at_or_after(creeping, 0.05) == creeping[3]
    assert first_sample_at_or_after(creeping, 0.0) == creeping[0]   # the first sample of all
    kept_last_five = deque(creeping, maxlen=5)
    assert first_sample_at_or_after(kept_last_five, 0.15) == creeping[8]
    with pytest.raises(RunFailed, match=r'odometry sample at t=0\.050 s is no longer kept'):
        first_sample_at_or_after(kept_last_five, 0.05)


def test_markers_read_the_captures_where_the_controller_reads_them():
    bare = GraphOptions(goal_m=(0.1, 0.0), controller_overrides={'capture_uncertainty': 'fixed'})
    assert node_overrides(MARKERS_NODE, bare)['capture_uncertainty'] == 'fixed'
    assert node_overrides(MARKERS_NODE, GraphOptions(goal_m=(0.1, 0.0)))[
        'capture_uncertainty'] == 'covariance'


@pytest.mark.parametrize('tolerance, passed', [(5e-6, 5e-6), (5, 5.0), ('five', None),
                                               ([1.0], None)])
def test_markers_are_handed_the_controller_s_tolerance_only_of_the_type_they_declare(tolerance,
                                                                                       passed):
    """A wrong one is the controller's to refuse, named: handed on, whichever of the two
    nodes refused it first was named ("five" once blamed on markers_node, in rclpy's words)."""
    options = GraphOptions(goal_m=(0.1, 0.0), controller_overrides={'tolerance_m': tolerance})
    assert node_overrides(MARKERS_NODE, options).get('tolerance_m') == passed


def captures_awaited(executable: str, options: GraphOptions) -> dict[str, object]:
    told = node_overrides(NodeSpec('omni_micro_vision', executable), options)
    return {name: told[name] for name in ('capture_readers', 'covariance_readers',
                                          'motion_readers')}


def test_the_tracker_waits_for_the_readers_of_its_captures_as_vision_does():
    images = GraphOptions(goal_m=(0.1, 0.0), vision='images', record=Path('bag'))
    assert captures_awaited('tracker_node', images) == {
        'capture_readers': ['bag_recorder'],
        'covariance_readers': ['controller_node', 'markers_node', 'bag_recorder'],
        'motion_readers': []}


def test_a_camera_waits_for_the_servo_and_the_recorder_on_its_captures_in_motion():
    servo: dict[str, object] = {'mode': 'servo'}
    for executable, vision in (('tracker_node', 'images'), ('vision_node', 'model')):
        options = GraphOptions(goal_m=(0.1, 0.0), vision=vision, record=Path('bag'),
                               controller_overrides=servo)
        assert captures_awaited(executable, options)['motion_readers'] == [
            'controller_node', 'bag_recorder']
    # Published for the recorder alone, they wait for it alone.
    watched = GraphOptions(goal_m=(0.1, 0.0), record=Path('bag'), captures_in_motion=True)
    assert captures_awaited('vision_node', watched)['motion_readers'] == ['bag_recorder']


def test_vision_waits_for_the_readers_of_its_captures_on_the_topics_they_read():
    recorded = GraphOptions(goal_m=(0.1, 0.0), record=Path('bag'))
    assert captures_awaited('vision_node', recorded) == {
        'capture_readers': ['bag_recorder'],
        'covariance_readers': ['controller_node', 'markers_node', 'bag_recorder'],
        'motion_readers': []}
    bare = GraphOptions(goal_m=(0.1, 0.0), composed=True,
                        controller_overrides={'capture_uncertainty': 'fixed'})
    assert captures_awaited('vision_node', bare) == {
        'capture_readers': ['controller_node', 'markers_node'], 'covariance_readers': [],
        'motion_readers': []}


def test_composed_refuses_what_needs_separate_processes():
    with pytest.raises(UsageError, match=r'--respawn .* choose one'):
        all_specs(GraphOptions(goal_m=(0.1, 0.0), composed=True, respawn=True))
    stand_in = NodeSpec('x', 'vision_node', command=('camera-driver',))
    with pytest.raises(UsageError, match='installed nodes only, not the command of vision_node'):
        all_specs(GraphOptions(goal_m=(0.1, 0.0), composed=True,
                               nodes=[NodeSpec('omni_micro_sim', 'dynamics_node'), stand_in]))
