"""What the orchestration tells each node beyond the graph's params file: the lockstep's and the
readers' wiring, the seed, and values one node must share with another (markers_node draws the
cameras' fields, the tracker blurs as the rendering camera exposes).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from omni_micro_bringup.composition import (
    MARKERS_FROM_VISION,
    all_specs,
    awaited_readers,
    camera_node_of,
    coordinator_name,
    lockstep_nodes,
    orchestration_odometry_topic,
)
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_bringup.params_files import (
    graph_params_file,
    node_parameters,
    params_from_files,
)
from omni_micro_bringup.robot_namespaces import (
    namespaced_params,
    robot_modes,
    robot_names,
    robots_in_motion,
)
from omni_micro_common.lockstep_groups import qualified_node_name
from omni_micro_common.topic_names import CAPTURE_TOPICS, camera_info_beside
from omni_micro_control.fleet_files import controller_settings
from omni_micro_control.servo_config import SERVO_MODE
from omni_micro_sim.parameters import DEFAULT_PERIOD_S
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.motion_capture import CameraTiming, capture_age_bound_s
from omni_micro_vision.scene import FLEET_COLOURS

# The graph's nodes that must have every move: the robot and the two in the lockstep with it.
TRAJECTORY_READERS = ('dynamics_node', 'markers_node', 'bag_recorder')


@dataclass(frozen=True)
class GraphWiring:
    """What every node's overrides are worked out from, worked out once per graph (a fleet of
    42 robots has some 130 nodes)."""

    specs: list[NodeSpec]        # all_specs
    present: set[str]            # the executables of every node started, hosted ones too
    robots: list[str]            # the robots' namespaces
    modes: list[str]             # each robot's controller mode
    in_motion: list[str]         # the robots whose captures in motion are published

    @classmethod
    def of(cls, options: GraphOptions) -> GraphWiring:
        specs = all_specs(options)
        return cls(specs, {hosted.executable for spec in specs
                           for hosted in (spec.hosts or (spec,))},
                   robot_names(options), robot_modes(options), robots_in_motion(options))


def wired_specs(options: GraphOptions, folder: Path | None = None) -> list[NodeSpec]:
    """Every process of the graph as it starts (:func:`~.composition.all_specs`), each node
    with its params files (the package's, then the user's; a robot's in a namespace, written
    in ``folder`` with its sections renamed there) and its overrides; a process given as a
    command is started as it is."""
    params = (graph_params_file(), *options.params_files)
    wiring = GraphWiring.of(options)
    robots = [robot for robot in wiring.robots if robot]
    own: dict[str, tuple[Path, ...]] = {}
    if robots:
        if folder is None:
            raise ValueError('the params files of robots in namespaces are written in a folder')
        own = {robot: tuple(namespaced_params(list(params), robot, folder)) for robot in robots}

    def wired(spec: NodeSpec) -> NodeSpec:
        if spec.command is not None:
            return spec
        if spec.hosts:
            return replace(spec, hosts=tuple(wired(hosted) for hosted in spec.hosts))
        return replace(spec, params=own.get(spec.namespace, params),
                       overrides=node_overrides(spec, options, wiring))

    return [wired(spec) for spec in wiring.specs]


def node_overrides(spec: NodeSpec, options: GraphOptions,
                   wiring: GraphWiring | None = None) -> dict[str, object]:
    """What ``spec``'s node is told beyond the params files: the lockstep's and the readers'
    wiring, the seed, values it must share with another node, and what a robot of a fleet has
    of its own (its start, its wheels, its controller mode, its colour)."""
    overrides: dict[str, object] = {}
    wiring = wiring or GraphWiring.of(options)
    robots, present, fleet = wiring.robots, wiring.present, options.fleet
    robot = robots.index(spec.namespace) if spec.namespace in robots else 0
    # The readers of a node's latched status that must have its first (status_readers).
    recorder = recorder_of(present)

    def capture_readers_of(namespaces: list[str]) -> dict[str, list[str]]:
        """A camera's readers: the controller and markers_node of each of ``namespaces``, and
        of the captures in motion the servos among those controllers."""
        servos = [qualified_node_name(namespace, 'controller_node') for namespace in namespaces
                  if namespace in wiring.in_motion and 'controller_node' in present
                  and wiring.modes[robots.index(namespace)] == SERVO_MODE]
        return capture_readers(options, [qualified_node_name(namespace, name)
                                         for namespace in namespaces
                                         for name in ('controller_node', 'markers_node')
                                         if name in present], present, servos,
                               in_motion=all(ns in wiring.in_motion for ns in namespaces))

    if spec.executable == 'dynamics_node':
        # Time 0 waits until the orchestration has seen every node listening.
        overrides.update(paused=True, real_time_factor=float(options.real_time_factor))
        if fleet is not None:
            overrides.update(robots=robots, robot_poses=[
                float(v) for x, y in fleet.plan.starts_m for v in (x, y, 0.0)],
                robot_wheel_offsets_rad=[float(v) for true_robot in fleet.robots
                                         for v in true_robot.wheel_offsets_rad])
        specs = wiring.specs
        # A fleet's orchestration takes part as each robot's coordinator (fleet_dispatch).
        coordinators = [coordinator_name(name) for name in robots] if fleet else []
        overrides.update(lockstep_nodes=lockstep_nodes(specs, coordinators)
                         if options.in_lockstep else [])
        # Time waits for the readers of every node of the graph that must have the robots'
        # streams from the first sample (READS_FROM_ROBOT).
        overrides.update(awaited_readers=awaited_readers(
            specs, robots, orchestration_odometry_topic(options.follow_route)))
        if options.external:
            # Beside a real camera: stamps on the wall clock, at real time.
            overrides.update(stamp_origin='wall', real_time_factor=1.0)
        overrides.update(options.dynamics_overrides)
    elif spec.executable in ('vision_node', 'camera_node'):
        # A fleet's robots each their captures' own noise, as the fleet twin draws it.
        seed = int(options.seed) * 1000 + robot if spec.namespace else int(options.seed)
        overrides.update(seed=seed)
        if spec.executable == 'vision_node':
            overrides.update(capture_readers_of([spec.namespace]))
            overrides.update(status_readers=recorder)
            if spec.namespace in wiring.in_motion:
                overrides.update(captures_in_motion=True)
        if spec.executable == 'camera_node':
            if fleet is not None:
                overrides.update(robots=robots)   # each drawn with its code
            # Its first frame waits for the readers that must not miss it.
            readers = ['tracker_node'] if 'tracker_node' in present else []
            if options.record_images:
                readers.append('bag_recorder')
            overrides.update(image_readers=readers)
        overrides.update(options.vision_overrides)
    elif spec.executable == 'tracker_node':
        if fleet is not None:
            overrides.update(robots=robots)   # named by their codes
        overrides.update(capture_readers_of(robots))
        if wiring.in_motion:
            overrides.update(captures_in_motion=True)
        if options.camera == 'simulated':
            # camera_node publishes reliable, and in the lockstep a lost frame would be a frame
            # never reported: time would stand still. A driver's frames are read best effort.
            overrides.update(image_reliability='reliable')
            if wiring.in_motion:
                overrides.update(rendered_motion(options.params_files, options.vision_overrides))
        if options.image_topics:
            overrides.update(cameras=sorted(options.image_topics))
            for camera, topic in options.image_topics.items():
                overrides.update({f'{camera}.image_topic': topic,
                                  f'{camera}.info_topic': camera_info_beside(topic)})
    elif spec.executable == 'markers_node':
        # Its first array waits for the reader that must not miss it.
        overrides.update(markers_readers=recorder)
        overrides.update(markers_told(options.params_files, camera_node_of(options),
                                      options.vision_overrides, options.dynamics_overrides,
                                      options.controller_overrides))
        if fleet is not None:
            overrides.update({
                'robot.wheel_offsets_rad': [float(v)
                                            for v in fleet.robots[robot].wheel_offsets_rad],
                'robot.colour': list(FLEET_COLOURS[robot % len(FLEET_COLOURS)]),
                'robot.label': spec.namespace})
    elif spec.executable == 'controller_node':
        # Its first move and its first status wait for the readers that must not miss them.
        overrides.update(trajectory_readers=[
            qualified_node_name(spec.namespace, name) if name == 'markers_node' else name
            for name in TRAJECTORY_READERS if name in present], status_readers=recorder)
        if options.open_loop_s is not None:
            overrides.update(open_loop_duration_s=float(options.open_loop_s))
        overrides.update(options.controller_overrides)
        mode = wiring.modes[robot]
        if fleet is not None:
            # Each goal counts from the end it follows, which the coordinator stamps it with.
            overrides.update(goal_time='stamp', **controller_settings(mode))
        if mode == SERVO_MODE:
            overrides.update(servo_timing(options))
    overrides.update(spec.overrides)
    return overrides


def markers_told(params_files: tuple[Path, ...], camera: str,
                 vision_overrides: dict[str, object], dynamics_overrides: dict[str, object],
                 controller_overrides: dict[str, object]) -> dict[str, object]:
    """What markers_node draws as other nodes have it: the cameras' fields as ``camera`` (the
    one in use: camera_node has vision_node's names) has them, the robot's wheel offsets, the
    controller's tolerance and the captures it reads; each only if of the kind markers_node
    declares (:func:`passed_on`)."""
    vision = node_parameters(camera, params_files, vision_overrides)
    dynamics = node_parameters('dynamics_node', params_files, dynamics_overrides)
    controller = node_parameters('controller_node', params_files, controller_overrides)
    sources = [*((name, vision) for name in MARKERS_FROM_VISION),
               ('robot.wheel_offsets_rad', dynamics), ('tolerance_m', controller),
               ('capture_uncertainty', controller)]
    declared = params_from_files('markers_node')
    told: dict[str, object] = {}
    for name, source in sources:
        value = passed_on(source.get(name), declared[name])
        if value is not None:
            told[name] = value
    return told


def rendered_motion(params_files: tuple[Path, ...],
                    vision_overrides: dict[str, object]) -> dict[str, object]:
    """What tracker_node must know of camera_node's frames to place a capture in motion: each
    camera's blur (its exposure) and the stamp's place in it (camera_node stamps a frame at its
    exposure's start)."""
    rendering = node_parameters('camera_node', params_files, vision_overrides)
    timing: dict[str, object] = {}
    for name in CAPTURE_TOPICS:
        exposure = rendering.get(f'{name}.exposure_s')
        if isinstance(exposure, (int, float)):
            timing.update({f'{name}.motion.exposure_s': float(exposure),
                           f'{name}.motion.mid_exposure_after_stamp_s': 0.5 * float(exposure)})
    return timing


def servo_timing(options: GraphOptions) -> dict[str, object]:
    """The servo's ``servo.capture_age_s`` and ``servo.command_period_s`` as this graph's
    cameras and robot make them: how old a capture in motion can be when it arrives, and the
    grid the robot starts commands on, as the twin has them. A real camera or robot says
    neither: then the params say."""
    if options.external:
        return {}
    return servo_timing_of(options.params_files, camera_node_of(options),
                           options.dynamics_overrides, options.vision_overrides)


def servo_timing_of(params_files: tuple[Path, ...], camera: str = 'vision_node',
                    dynamics_overrides: dict[str, object] | None = None,
                    vision_overrides: dict[str, object] | None = None) -> dict[str, object]:
    """:func:`servo_timing` of a simulated robot seen by ``camera`` (vision_node, or
    camera_node's rendered images), its nodes' parameters from ``params_files`` and the
    overrides."""
    vision = node_parameters(camera, params_files, vision_overrides or {})
    try:
        period = _grid_period_s(params_files, dynamics_overrides)
        if camera == 'vision_node':
            timings = [CameraTiming(**{name: _number(vision[f'{camera_name}.motion.{name}'])
                                       for name in CameraTiming.__dataclass_fields__
                                       if f'{camera_name}.motion.{name}' in vision})
                       for camera_name in CAPTURE_TOPICS]
        else:
            # The tracker publishes a frame's capture once it has tracked it, which the lockstep
            # holds the robot for: no later than the frame's exposure allows.
            timings = [CameraTiming(exposure_s=_number(vision.get(f'{camera_name}.exposure_s',
                                                                  CameraTiming.exposure_s)))
                       for camera_name in CAPTURE_TOPICS]
    except (CameraConfigError, TypeError):
        return {}   # the node given the bad value refuses it, naming it
    return {'servo.capture_age_s': capture_age_bound_s(timings, period),
            'servo.command_period_s': period}


def grid_period_s(params_files: tuple[Path, ...],
                  dynamics_overrides: dict[str, object] | None = None) -> float:
    """The simulated robots' grid period, dynamics_node's ``publish_period_s`` as the params
    and overrides give it (the default if it is no number: the node refuses it, naming it)."""
    try:
        return _grid_period_s(params_files, dynamics_overrides)
    except TypeError:
        return DEFAULT_PERIOD_S


def _grid_period_s(params_files: tuple[Path, ...],
                   dynamics_overrides: dict[str, object] | None) -> float:
    dynamics = node_parameters('dynamics_node', params_files, dynamics_overrides or {})
    return _number(dynamics.get('publish_period_s', DEFAULT_PERIOD_S))


def _number(value: object) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f'{value!r} is no number')
    return float(value)


def passed_on(value: object, like: object) -> object | None:
    """A value of another node's params of the kind markers_node declares (``like``: a string,
    a number, or a list of numbers; numbers as floats, the way ROS types them), or None when it
    is not: its own node then refuses it, naming it. Passed on, a wrong one was refused by
    whichever of the two nodes came first (tolerance_m: 5 blamed on markers_node, which refused
    the integer first; tolerance_m: "five" once, idle, in a clean-clone run of the suite)."""
    def number(item: object) -> float | None:
        return float(item) if isinstance(item, (int, float)) and not isinstance(item, bool) \
            else None

    if isinstance(like, str):
        return value if isinstance(value, str) else None
    if isinstance(like, list):
        numbers = [number(v) for v in value] if isinstance(value, list) else [None]
        return numbers if None not in numbers else None
    return number(value)


def capture_readers(options: GraphOptions, readers: list[str], present: set[str],
                    servos: list[str], in_motion: bool) -> dict[str, list[str]]:
    """vision_node's (or tracker_node's) ``capture_readers`` (bare topics),
    ``covariance_readers`` and ``motion_readers`` in this graph: ``readers`` (the controllers
    and markers_nodes it captures for, each as its node is named) on the bare topics if the
    controller's ``capture_uncertainty`` is ``fixed``, else on those with the covariance;
    ``servos`` on the captures in motion; the recorder, if ``present``, on all of them, those in
    motion if it records them for every robot the camera captures (``in_motion``: a tracker
    shared by a servo and a robot of another mode publishes both robots' captures in motion,
    and the recorder reads the servo's alone)."""
    fixed = node_parameters('controller_node', options.params_files, options.controller_overrides
                            ).get('capture_uncertainty', 'covariance') == 'fixed'
    recorder = recorder_of(present)
    return {'capture_readers': (readers if fixed else []) + recorder,
            'covariance_readers': ([] if fixed else readers) + recorder,
            'motion_readers': servos + (recorder if in_motion else [])}


def recorder_of(present: set[str]) -> list[str]:
    """The recorder, as a reader some writer must match first, if the graph has one."""
    return ['bag_recorder'] if 'bag_recorder' in present else []
