"""One robot is a fleet of one: ``run --robots`` and ``fleet --graph`` are two doors to the one
run sequence (graph.run_graph), every node of a fleet is started as a single robot's nodes are
(its command line built from its spec, never a command given in its place), and a run of one
robot without a goal is refused, named."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from omni_micro_bringup import graph
from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.fleet_dispatch import first_tick_past
from omni_micro_bringup.graph_options import FleetRun, GraphOptions
from omni_micro_bringup.graph_result import GraphResult, RobotLog
from omni_micro_bringup.node_overrides import wired_specs
from omni_micro_bringup.node_spec import NodeSpec, composed, process_argv
from omni_micro_bringup.readiness import (
    external_publications,
    loop_subscriptions,
    ready_subscriptions,
)
from omni_micro_cli.cli import main
from omni_micro_control.fleet_plan import plan_fleet
from omni_micro_sim.parameters import RobotParameters
from omni_micro_sim.stepper import GridSimulator


def two_robots(folder: Path, controllers: tuple[str, ...] = ('paper', 'paper'),
               **options: Any) -> list[NodeSpec]:
    """What the graph starts for two robots (at 0 and 50 mm), as ``fleet --graph`` has it."""
    plan = plan_fleet([(0.0, 0.0), (0.05, 0.0)], [[], []])
    options.setdefault('markers', False)
    return wired_specs(GraphOptions(seed=1, real_time_factor=math.inf, **options,
                                    fleet=FleetRun(plan, [RobotParameters()] * 2,
                                                   list(controllers))), folder)


def asked_of_the_graph(monkeypatch, argv: list[str]) -> GraphOptions:
    """The options ``omni-micro argv`` hands run_graph (stood in for: no graph starts)."""
    asked: list[GraphOptions] = []

    def run_graph(options: GraphOptions) -> GraphResult:
        asked.append(options)
        assert options.fleet is not None
        count = len(options.fleet.plan.starts_m)
        logs = [RobotLog(tasks_done_s=[1.0] * len(tasks), route=[(0.0, 0.0, 0.0, 0.0)])
                for tasks in options.fleet.plan.tasks]
        return GraphResult('done', 'every task done in 1.00 s', 1.0, 0.5, options.log_dir, 7,
                           robots=logs, closest_gap_m=0.02,
                           closest_pair=(0, 1) if count > 1 else None)

    monkeypatch.setattr(graph, 'run_graph', run_graph)
    assert main(argv) == 0
    (options,) = asked
    return options


def test_run_robots_and_fleet_graph_hand_the_graph_the_same_run(monkeypatch, tmp_path, capsys):
    common = ['--robots', '3', '--seed', '4', '--rtf', '2', '--log-dir', str(tmp_path),
              '--vision', 'images', '--controller', 'model']
    through_run = asked_of_the_graph(monkeypatch, ['run', *common, '--timeout', '3600',
                                                   '--no-markers'])
    through_fleet = asked_of_the_graph(monkeypatch, ['fleet', '--graph', *common])
    capsys.readouterr()
    assert through_run.fleet is not None and through_fleet.fleet is not None
    for name in ('seed', 'real_time_factor', 'log_dir', 'timeout_s', 'markers', 'vision',
                 'composed', 'record', 'view', 'goal_m'):
        assert getattr(through_run, name) == getattr(through_fleet, name), name
    assert through_run.real_time_factor == 2.0 and through_run.goal_m is None
    run_fleet, fleet_fleet = through_run.fleet, through_fleet.fleet
    assert run_fleet.controllers == fleet_fleet.controllers == ['model'] * 3
    assert run_fleet.robots == fleet_fleet.robots
    assert run_fleet.plan.starts_m == fleet_fleet.plan.starts_m
    assert run_fleet.plan.tasks == fleet_fleet.plan.tasks
    assert run_fleet.max_sim_time_s == fleet_fleet.max_sim_time_s == 1800.0


def test_the_two_doors_take_the_same_fleet_flags(monkeypatch, tmp_path, capsys):
    common = ['--robots', '2', '--seed', '1', '--goals-per-robot', '1', '--max-sim-time', '900',
              '--log-dir', str(tmp_path)]
    plots = {door: tmp_path / f'{door}.png' for door in ('run', 'fleet')}
    through_run = asked_of_the_graph(monkeypatch, ['run', *common, '--timeout', '3600',
                                                   '--no-markers', '--plot', str(plots['run'])])
    through_fleet = asked_of_the_graph(monkeypatch, ['fleet', '--graph', *common, '--plot',
                                                     str(plots['fleet'])])
    capsys.readouterr()
    assert through_run.fleet is not None and through_fleet.fleet is not None
    assert through_run.fleet.plan.tasks == through_fleet.fleet.plan.tasks
    assert [len(tasks) for tasks in through_run.fleet.plan.tasks] == [1, 1]
    assert through_run.fleet.max_sim_time_s == through_fleet.fleet.max_sim_time_s == 900.0
    assert all(plot.read_bytes().startswith(b'\x89PNG') for plot in plots.values())


@pytest.mark.parametrize('composed_loop', [False, True])
def test_a_fleet_s_nodes_are_started_as_a_single_robot_s_are(tmp_path, composed_loop):
    specs = two_robots(tmp_path, record=tmp_path / 'bag', composed=composed_loop, markers=True)
    hosted = [inner for spec in specs for inner in (spec.hosts or (spec,))]
    assert all(spec.command is None for spec in [*specs, *hosted])
    names = [spec.name for spec in hosted]
    assert names == ['dynamics_node', *(f'robot_{k}.{node}' for k in (0, 1) for node in (
        'vision_node', 'controller_node', 'markers_node')), 'bag_recorder']
    controller = next(spec for spec in hosted if spec.name == 'robot_1.controller_node')
    argv = process_argv(controller)
    # Its namespace and topics remapped first, then its params files (robot_1's sections),
    # then what it alone is told.
    assert argv[1:4] == ['--ros-args', '-r', '__ns:=/robot_1']
    assert '/odom:=/robot_1/odom' in argv
    files = [argv[i + 1] for i, word in enumerate(argv) if word == '--params-file']
    assert files == [str(path) for path in controller.params]
    assert files[-1].endswith('robot_1.params.0.yaml')
    assert 'goal_time:=stamp' in argv and argv.index('goal_time:=stamp') > argv.index(files[-1])
    if composed_loop:
        # Each robot's markers_node is hosted with its robot's nodes, none a process of its own.
        assert [spec.name for spec in specs if not spec.hosts] == ['bag_recorder']
        # However many containers this machine's cores make, one hosts robot_1's controller.
        container = process_argv(next(spec for spec in specs if controller in spec.hosts))
        # The container hosts each node with the very arguments its own process would have.
        start = [i for i, word in enumerate(container)
                 if word == 'omni_micro_control.controller_node'][1]   # robot_1's
        assert container[start + 1:start + len(argv)] == argv[1:]
        assert container[start + len(argv)] == '--'


@pytest.mark.parametrize('vision, mode', [('model', 'paper'), ('model', 'servo'),
                                          ('images', 'servo'), ('images', 'model')])
def test_a_fleet_s_robot_is_told_what_a_single_robot_is_and_what_is_its_own_beside(
        tmp_path, vision, mode):
    """One composition for 1..N robots: each node of robot_1 is told what the single robot's
    is, its readers named in its namespace; beside that only what is its own (its captures'
    seed, its goals stamped by the coordinator, its offsets, colour and label)."""
    own = {'vision_node': {'seed'}, 'controller_node': {'goal_time'},
           'markers_node': {'robot.wheel_offsets_rad', 'robot.colour', 'robot.label'}}

    def told(specs, namespace):
        def unqualified(value):
            return [str(item).removeprefix(f'{namespace}/') for item in value] \
                if isinstance(value, list) else value
        hosted = [inner for spec in specs for inner in (spec.hosts or (spec,))]
        return {spec.executable: {name: unqualified(value)
                                  for name, value in spec.overrides.items()}
                for spec in hosted if spec.namespace == namespace}

    single = told(wired_specs(GraphOptions(goal_m=(0.1, 0.0), seed=1, real_time_factor=math.inf,
                                           vision=vision, record=tmp_path / 'one' / 'bag',
                                           controller_overrides={'mode': mode})), '')
    fleet = two_robots(tmp_path, (mode, mode), vision=vision, markers=True,
                       record=tmp_path / 'bag')
    robot_1 = told(fleet, 'robot_1')
    robot_nodes = {'controller_node', 'markers_node',
                   *(('vision_node',) if vision == 'model' else ())}
    assert set(robot_1) == robot_nodes
    for node in robot_nodes:
        assert {name: value for name, value in robot_1[node].items()
                if name not in own[node]} == {
            name: value for name, value in single[node].items() if name not in own[node]}, node
    assert robot_1['controller_node']['goal_time'] == 'stamp'
    assert 'goal_time' not in single['controller_node']
    if vision == 'model':
        assert (single['vision_node']['seed'], robot_1['vision_node']['seed']) == (1, 1001)
    # A servo reads how old the tracker's frames come on the tracker's own topics: a shared
    # tracker's are not remapped into the robot's namespace.
    (controller,) = [spec for spec in fleet if spec.name == 'robot_1.controller_node']
    assert ('/camera/macro/tracker_status:=/robot_1/camera/macro/tracker_status'
            in controller.remaps) == (vision == 'model')


@pytest.mark.parametrize('vision', ['model', 'images'])
def test_one_wiring_tells_time_whom_to_wait_for_in_a_fleet_and_a_single_robot(tmp_path, vision):
    """dynamics_node's lockstep_nodes and awaited_readers come from the same functions for N
    robots and for one: every node that reports is waited for by the name it reports under,
    and every reader of the robots' streams is awaited in its robot's namespace."""
    def dynamics_of(specs):
        hosted = [inner for spec in specs for inner in (spec.hosts or (spec,))]
        return next(spec for spec in hosted if spec.executable == 'dynamics_node').overrides

    fleet = dynamics_of(two_robots(tmp_path, record=tmp_path / 'bag', markers=True,
                                   vision=vision))
    robots = ('robot_0', 'robot_1')
    assert set(fleet['lockstep_nodes']) == {
        *(f'{robot}/{node}' for robot in robots for node in (
            'controller_node', 'markers_node', 'omni_micro_orchestration',
            *(('tracker_node',) if vision == 'images' else ('vision_node',)))),
        'bag_recorder', *(('camera_node',) if vision == 'images' else ())}
    odometry_reader = 'camera_node' if vision == 'images' else '{robot}/vision_node'
    for robot in robots:
        assert f'{odometry_reader.format(robot=robot)}:/{robot}/odom' in fleet['awaited_readers']
        assert f'{robot}/controller_node:/{robot}/joint_states' in fleet['awaited_readers']
        assert f'bag_recorder:/{robot}/wheel_slip' in fleet['awaited_readers']
        assert f'omni_micro_orchestration:/{robot}/odom_throttle' in fleet['awaited_readers']
    assert fleet['awaited_readers'].count('bag_recorder:/clock') == 1

    single = dynamics_of(wired_specs(GraphOptions(goal_m=(0.1, 0.0), vision=vision,
                                                  record=tmp_path / 'one' / 'bag')))
    # The fleet of one in the root namespace: bare names and topics, the orchestration only
    # reading (a single robot's goals wait for no coordinator).
    assert set(single['lockstep_nodes']) == {
        'controller_node', 'markers_node', 'bag_recorder',
        *(('camera_node', 'tracker_node') if vision == 'images' else ('vision_node',))}
    assert {f'{odometry_reader.format(robot="").strip("/")}:/odom',
            'controller_node:/joint_states', 'bag_recorder:/clock',
            'omni_micro_orchestration:/odom_throttle'} <= set(single['awaited_readers'])


@pytest.mark.parametrize('vision', ['model', 'images'])
def test_each_robots_camera_waits_for_its_servo_on_the_captures_in_motion(tmp_path, vision):
    """The servo acts on its robot's captures in motion, the recorder keeps every robot's: the
    camera's writers of them wait for both, so that neither misses the first (a sample sent
    before its reader is matched is lost to it)."""
    camera = 'tracker_node' if vision == 'images' else 'vision_node'

    def motion_readers(controllers: tuple[str, str]) -> list[object]:
        fleet = two_robots(tmp_path, controllers=controllers, vision=vision,
                           record=tmp_path / 'bag')
        return [inner.overrides['motion_readers'] for spec in fleet
                for inner in (spec.hosts or (spec,)) if inner.executable == camera]

    servo = ['robot_0/controller_node', 'bag_recorder']
    if vision == 'images':
        # One tracker for both: the recorder keeps the servo's captures in motion alone, so the
        # tracker, which publishes both robots', waits for the servo alone (waiting for the
        # recorder on robot_1's, which it never reads, the graph would never come up).
        assert motion_readers(('servo', 'paper')) == [['robot_0/controller_node']]
        assert motion_readers(('servo', 'servo')) == [
            ['robot_0/controller_node', 'robot_1/controller_node', 'bag_recorder']]
    else:
        assert motion_readers(('servo', 'paper')) == [servo, []]


@pytest.mark.parametrize('vision', ['model', 'images'])
def test_one_wiring_tells_the_cameras_which_captures_the_controllers_read(tmp_path, vision):
    """With ``capture_uncertainty: fixed`` (a camera without covariance) the controllers read
    the bare captures: the camera (vision_node, or the tracker every robot shares) waits for
    them there, markers_node reads there too, and time may start once they do, for N robots
    as for one. (The fleet's own wiring named them on the covariance topics: its graph never
    came up.)"""
    params = tmp_path / 'bare.yaml'
    params.write_text('controller_node:\n  ros__parameters:\n    capture_uncertainty: fixed\n')
    camera = 'tracker_node' if vision == 'images' else 'vision_node'

    def told(specs, executable):
        hosted = [inner for spec in specs for inner in (spec.hosts or (spec,))]
        return [spec.overrides for spec in hosted if spec.executable == executable]

    fleet = two_robots(tmp_path, params_files=(params,), markers=True, vision=vision)
    robots = [('robot_0',), ('robot_1',)] if vision == 'model' else [('robot_0', 'robot_1')]
    assert [(overrides['capture_readers'], overrides['covariance_readers'])
            for overrides in told(fleet, camera)] == [
        ([f'{robot}/{node}' for robot in shared for node in ('controller_node', 'markers_node')],
         []) for shared in robots]
    assert {markers['capture_uncertainty'] for markers in told(fleet, 'markers_node')} == {
        'fixed'}
    single = wired_specs(GraphOptions(goal_m=(0.1, 0.0), vision=vision, params_files=(params,)))
    (alone,) = told(single, camera)
    assert (alone['capture_readers'], alone['covariance_readers']) == (
        ['controller_node', 'markers_node'], [])
    assert told(single, 'markers_node')[0]['capture_uncertainty'] == 'fixed'
    # Time waits for a reader of each camera's captures, bare or with covariance, in each
    # robot's namespace.
    assert ('/robot_1/camera/micro/pose', '/robot_1/camera/micro/pose_with_covariance') in \
        loop_subscriptions(odometry=True, robots=('robot_0', 'robot_1'))
    assert ('/camera/micro/pose', '/camera/micro/pose_with_covariance') in loop_subscriptions(
        odometry=True)


def test_a_shared_tracker_places_captures_in_motion_in_the_blur_the_camera_renders(tmp_path):
    """Servos on rendered images: the tracker every robot shares is told camera_node's
    exposure (from the params files) and where a frame's stamp lies in it, as a single robot's
    tracker is. (The fleet's kept the tracker's own 4 ms: with camera_node's 8 ms, a capture
    in motion was placed 2 ms before its exposure's middle.)"""
    params = tmp_path / 'slow_shutter.yaml'
    params.write_text('camera_node:\n  ros__parameters:\n    macro:\n      exposure_s: 0.008\n')

    def tracker_of(specs):
        hosted = [inner for spec in specs for inner in (spec.hosts or (spec,))]
        return next(spec for spec in hosted if spec.executable == 'tracker_node').overrides

    fleet = tracker_of(two_robots(tmp_path, ('servo', 'paper'), params_files=(params,),
                                  vision='images'))
    single = tracker_of(wired_specs(GraphOptions(goal_m=(0.1, 0.0), vision='images',
                                                 params_files=(params,),
                                                 controller_overrides={'mode': 'servo'})))
    for told in (fleet, single):
        assert (told['macro.motion.exposure_s'], told['macro.motion.mid_exposure_after_stamp_s'],
                told['micro.motion.exposure_s']) == (0.008, 0.004, 0.004)


@pytest.mark.parametrize('vision', ['model', 'images'])
def test_a_fleet_s_markers_are_told_what_a_single_robot_s_are(tmp_path, vision):
    """markers_node draws the cameras' fields as the camera in use has them (a params file's
    vision_node section) and the controller's tolerance, in a fleet as for one robot; what is
    each robot's own (its offsets, colour and label) beside. (A fleet's drew the markers
    section's own fields, whatever the cameras' were.)"""
    params = tmp_path / 'wider.yaml'
    section = 'camera_node' if vision == 'images' else 'vision_node'
    params.write_text(f'{section}:\n  ros__parameters:\n    macro:\n'
                      '      field_m: [0.2, 0.16]\n'
                      'controller_node:\n  ros__parameters:\n    tolerance_m: 5.0e-6\n')

    def markers_of(specs):
        hosted = [inner for spec in specs for inner in (spec.hosts or (spec,))]
        return [spec.overrides for spec in hosted if spec.executable == 'markers_node']

    fleet = markers_of(two_robots(tmp_path, params_files=(params,), markers=True,
                                  vision=vision))
    (single,) = markers_of(wired_specs(GraphOptions(goal_m=(0.1, 0.0), vision=vision,
                                                    params_files=(params,))))
    assert single['macro.field_m'] == [0.2, 0.16] and single['tolerance_m'] == 5e-6
    for k, told in enumerate(fleet):
        assert {name: told[name] for name in single if name != 'markers_readers'} == {
            **{name: value for name, value in single.items() if name != 'markers_readers'},
            'robot.wheel_offsets_rad': [0.0, 0.0, 0.0]}
        assert told['robot.label'] == f'robot_{k}'


@pytest.mark.parametrize('asked, refused', [
    ({'vision': 'images', 'vision_overrides': {'faults.drop_rate': 0.1}},
     "fault injection .* is vision_node's"),
    ({'record_images': True, 'vision': 'images'}, '--record-images needs --record BAG'),
    ({'composed': True, 'respawn': True}, '--respawn restarts a crashed node'),
    ({'vision': 'photos'}, "vision must be one of \\['images', 'model'\\], got 'photos'")])
def test_one_robot_and_a_fleet_are_refused_a_graph_that_cannot_be_in_the_same_words(
        tmp_path, asked, refused):
    """One check for 1..N robots, in the run sequence itself (before, a single robot's graph
    with camera faults on rendered images was refused by the command line only)."""
    from omni_micro_bringup.fleet_dispatch import FleetDispatch
    from omni_micro_bringup.goal_sequence import GoalSequence

    plan = plan_fleet([(0.0, 0.0), (0.05, 0.0)], [[], []])
    fleet = GraphOptions(fleet=FleetRun(plan, [RobotParameters()] * 2, ['paper'] * 2), **asked)
    for driver in (GoalSequence(GraphOptions(goal_m=(0.1, 0.0), **asked)),
                   FleetDispatch(fleet)):
        with pytest.raises(UsageError, match=refused):
            driver.check()


@pytest.mark.parametrize('source', ['simulated', 'external'])
def test_time_waits_for_each_robot_s_readers_and_drivers_as_for_a_single_robot_s(source):
    """One readiness for 1..N robots: the readers a single robot's loop must have, and on the
    bench the drivers that must publish, each robot's in its namespace."""
    plan = plan_fleet([(0.0, 0.0), (0.05, 0.0)], [[], []])
    asked = {'camera': source, 'robot': source}
    single = GraphOptions(goal_m=(0.1, 0.0), **asked)
    fleet = GraphOptions(fleet=FleetRun(plan, [RobotParameters()] * 2, ['paper'] * 2), **asked)
    assert ready_subscriptions(fleet) == [
        tuple(f'/{robot}{topic}' for topic in alternatives)
        for robot in ('robot_0', 'robot_1') for alternatives in ready_subscriptions(single)]
    assert ('/odom',) in ready_subscriptions(single) or source == 'external'
    cameras = {'/camera/macro/image_raw': 'the camera driver',
               '/camera/micro/image_raw': 'the camera driver'}
    assert external_publications(single) == (
        {'/joint_states': "the robot's driver", **cameras} if source == 'external' else {})
    assert external_publications(fleet) == (
        {'/robot_0/joint_states': "robot_0's driver", '/robot_1/joint_states': "robot_1's driver",
         **cameras} if source == 'external' else {})


def test_a_node_given_as_a_command_is_refused_by_the_container():
    stand_in = NodeSpec('omni_micro_vision', 'camera_node', command=('driver',))
    with pytest.raises(UsageError, match='camera_node'):
        composed([stand_in])


def test_a_single_robot_s_run_without_its_goal_is_refused_before_anything_starts(tmp_path):
    with pytest.raises(UsageError, match='needs its goal'):
        graph.run_graph(GraphOptions(log_dir=tmp_path / 'runs'))
    assert not (tmp_path / 'runs').exists()


@pytest.mark.parametrize('period_s', [0.02, 0.1, 0.03])
@pytest.mark.parametrize('limit_s', [0.0, 0.3, 8.0, 29.0, 600.0])
def test_a_fleet_graph_ends_its_time_at_the_tick_the_twin_stops_at(limit_s, period_s):
    """The twin steps its grid until a tick's time is past the limit (0.3 s is past 3 ticks
    of 0.1 s in floats): the graph ends its run at that tick, not a tick either side."""
    grid = GridSimulator(RobotParameters(), period_s=period_s)
    while grid.time_s <= limit_s:
        grid.advance()
    assert first_tick_past(limit_s, period_s) == grid.time_s
