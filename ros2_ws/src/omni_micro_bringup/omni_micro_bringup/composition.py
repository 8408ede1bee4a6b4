"""What a run starts, for one robot or several: the graph's nodes (node_spec.NodeSpec).

The simulation (dynamics; on rendered images the cameras and their tracker, which every robot
shares), each robot's own nodes in its namespace (:mod:`.robot_namespaces`: its vision_node,
controller_node and markers_node; a single robot's in the root namespace), then who only
listens (the recorder, the live view).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.node_spec import NodeSpec, composed
from omni_micro_bringup.params_files import node_parameters
from omni_micro_bringup.robot_namespaces import (
    ROBOT_NODE_NAMES,
    guarded,
    in_namespace,
    robot_modes,
    robot_names,
    robots_in_motion,
)
from omni_micro_common.lockstep_groups import qualified_node_name
from omni_micro_common.topic_names import (
    CAMERA_STATUS_TOPIC,
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    CLOCK_TOPIC,
    FLEET_GUARD_TOPIC,
    JOINT_STATES_THROTTLE_TOPIC,
    JOINT_STATES_TOPIC,
    MARKERS_TOPIC,
    ODOM_THROTTLE_TOPIC,
    ODOM_TOPIC,
    TRACKER_STATUS_TOPICS,
    WHEEL_SLIP_TOPIC,
    namespaced_topic,
)
from omni_micro_control.servo_config import SERVO_MODE

# The nodes of the graph, by name (a params file's sections name them): the loop, and those a
# graph may have besides (the rendered cameras and their tracker, the markers, the recorder, the
# live view).
GRAPH_NODE_NAMES = ('dynamics_node', 'vision_node', 'controller_node')
OPTIONAL_NODE_NAMES = ('markers_node', 'camera_node', 'tracker_node', 'bag_recorder',
                       'omni_micro_viewer')
# What each node reads from the simulated robot that it must have from the first sample: the
# robot's clock starts only once its publishers have matched these readers (dynamics_node's
# awaited_readers). A lockstep node that missed a sample would never report it, and time would
# stand still; markers_node draws and bag_recorder keeps the whole run. Seeing a reader in the
# ROS graph from another process is not enough: discovery runs each way at its own pace, and a
# bag once lacked a run's first odometry.
READS_FROM_ROBOT: dict[str, tuple[str, ...]] = {
    'vision_node': (ODOM_TOPIC,), 'camera_node': (ODOM_TOPIC,),
    'controller_node': (JOINT_STATES_TOPIC,),
    'markers_node': (ODOM_THROTTLE_TOPIC, JOINT_STATES_THROTTLE_TOPIC, WHEEL_SLIP_TOPIC),
    'bag_recorder': (CLOCK_TOPIC, ODOM_TOPIC, JOINT_STATES_TOPIC, WHEEL_SLIP_TOPIC)}
# The orchestrator's own node: it publishes goals, reads statuses and, from the first sample,
# the odometry it takes the run's final pose from (omni_micro_bringup.orchestrator); not part of
# the graph.
ORCHESTRATOR_NODE = 'omni_micro_orchestration'
RECORDER_NODE = 'bag_recorder'


def orchestration_odometry_topic(follow_route: bool) -> str:
    """The odometry the orchestration reads: all of it only to draw the route."""
    return ODOM_TOPIC if follow_route else ODOM_THROTTLE_TOPIC


# What stands for the cameras: vision_node's measurement model, or rendered images and the
# tracker that turns them into captures (what a real camera and its tracker would do).
VISION_MODES = {'model': (('omni_micro_vision', 'vision_node'),),
                'images': (('omni_micro_vision', 'camera_node'),
                           ('omni_micro_vision', 'tracker_node'))}
# What may come from the bench instead of the simulation (run --camera / --robot).
SOURCES = ('simulated', 'external')


def default_nodes(vision: str = 'model') -> list[NodeSpec]:
    if vision not in VISION_MODES:
        raise UsageError(f'vision must be one of {sorted(VISION_MODES)}, got {vision!r}')
    dynamics, _, controller = GRAPH_NODE_NAMES
    return [NodeSpec('omni_micro_sim', dynamics),
            *(NodeSpec(package, name) for package, name in VISION_MODES[vision]),
            NodeSpec('omni_micro_control', controller)]


def recorded_topics(robots: Sequence[str] = ('',), markers: bool = True,
                    without: tuple[str, ...] = (), in_motion: Sequence[str] = (),
                    cameras: Sequence[str] = tuple(CAPTURE_IN_MOTION_TOPICS),
                    images: Sequence[str] = ()) -> list[str]:
    """What a run's bag holds: /clock, and each robot's topics of the graph (GRAPH_TOPICS) in
    its namespace (``robots``; ``''`` the root one, a single robot's), /markers with
    ``markers``, none of ``without`` (topics nobody in the graph publishes); the ``images``
    cameras' streams; and the captures in motion of ``cameras`` of the robots ``in_motion``,
    whose servo (or the user) asked for them."""
    from omni_micro_tools.topics import GRAPH_TOPICS

    own = [topic for topic in GRAPH_TOPICS if topic != CLOCK_TOPIC and topic not in without
           and (markers or topic != MARKERS_TOPIC)]
    return [*(() if CLOCK_TOPIC in without else (CLOCK_TOPIC,)),
            *(namespaced_topic(robot, topic) for robot in robots for topic in own),
            *(f'/camera/{camera}/{stream}' for camera in images
              for stream in ('image_raw', 'camera_info')),
            *(namespaced_topic(robot, CAPTURE_IN_MOTION_TOPICS[camera]) for robot in in_motion
              for camera in cameras)]


def recorder_spec(bag: Path, storage: str, topics: list[str], frames: bool = False,
                  whole: bool = False) -> NodeSpec:
    """The recorder of ``topics``, taking part in the lockstep: the robots never run so far
    ahead of it that a stream's writer drops a sample it has not recorded (``lockstep_ticks``),
    and with ``frames`` (images among the topics) no frame is lost to a slow disk
    (``lockstep_frames``). ``whole``: the bag keeps every message received, not only up to the
    outcome's tail."""
    return NodeSpec('omni_micro_tools', RECORDER_NODE, overrides={
        'bag': str(bag), 'storage': storage, 'topics': topics, 'lockstep_frames': frames,
        'lockstep_ticks': True, 'end_at_outcome': not whole}, lockstep=True)


def viewer_spec(host: str, port: int, markers: bool, robots: Sequence[str] = ()) -> NodeSpec:
    """The live view; of a fleet's ``robots`` (namespaces), each one's topics."""
    return NodeSpec('omni_micro_tools', 'viewer', overrides={
        'host': host, 'port': int(port), 'markers': bool(markers),
        **({'robots': list(robots)} if robots else {})})


def lockstep_nodes(specs: list[NodeSpec], also: Sequence[str] = ()) -> list[str]:
    """dynamics_node's ``lockstep_nodes``: every node of ``specs`` that reports on /lockstep,
    as it names itself, and ``also`` (the orchestration's, where it coordinates)."""
    return [*(name for spec in specs for name in spec.lockstep_names), *also]


def awaited_readers(specs: list[NodeSpec], robots: Sequence[str],
                    orchestration_topic: str) -> list[str]:
    """dynamics_node's ``awaited_readers``: each node of ``specs`` (hosted ones too) with what
    it reads from the robots (READS_FROM_ROBOT), a robot's node in its namespace and a shared
    one in every robot's, then the orchestration's ``orchestration_topic`` of every robot."""
    entries: list[str] = []
    for reader in (hosted for spec in specs for hosted in (spec.hosts or (spec,))):
        node = qualified_node_name(reader.namespace, reader.executable)
        for topic in READS_FROM_ROBOT.get(reader.executable, ()):
            entries += [f'{node}:{topic}'] if topic == CLOCK_TOPIC else [
                f'{node}:{namespaced_topic(robot, topic)}'
                for robot in ((reader.namespace,) if reader.namespace else robots)]
    entries += [f'{ORCHESTRATOR_NODE}:{namespaced_topic(robot, orchestration_topic)}'
                for robot in robots]
    return list(dict.fromkeys(entries))


MARKERS_NODE = NodeSpec('omni_micro_vision', 'markers_node')
# What markers_node must draw as the other nodes see it: their parameters, passed on.
MARKERS_FROM_VISION = ('macro.center_m', 'macro.field_m', 'macro.yaw_rad', 'micro.center_m',
                       'micro.field_m', 'micro.yaw_rad')


def servo_mode(options: GraphOptions) -> bool:
    """Whether a controller runs the servo mode (``--controller servo`` or its params)."""
    return SERVO_MODE in robot_modes(options)


def publishes_in_motion(options: GraphOptions) -> bool:
    """Whether the vision side publishes captures of a moving robot: asked, or read by a
    servo."""
    return bool(robots_in_motion(options))


def coordinator_name(robot: str) -> str:
    """How the orchestration reports on /lockstep as ``robot``'s coordinator (a fleet's)."""
    return qualified_node_name(robot, ORCHESTRATOR_NODE)


def graph_nodes(options: GraphOptions) -> list[NodeSpec]:
    """The nodes closing the loop: those given, else the default set for ``options.vision``,
    less what the bench supplies (the robot's driver for dynamics_node; the camera's driver for
    camera_node, its images then read by tracker_node); the simulation's and the shared
    cameras' once, then each robot's own (ROBOT_NODE_NAMES) in its namespace."""
    if options.nodes:
        return list(options.nodes)
    nodes = default_nodes('images' if options.camera == 'external' else options.vision)
    replaced = {*(('camera_node',) if options.camera == 'external' else ()),
                *(('dynamics_node',) if options.robot == 'external' else ())}
    kept = [spec for spec in nodes if spec.executable not in replaced]
    robots = robot_names(options)
    shared = [spec for spec in kept if spec.executable not in ROBOT_NODE_NAMES]
    # A tracker every robot shares says how old its frames come on its own topics.
    statuses = tuple(TRACKER_STATUS_TOPICS.values()) \
        if any(spec.executable == 'tracker_node' for spec in shared) else ()
    # The tracker takes part in each robot's lockstep as that robot's (it gates its captures).
    shared = [replace(spec, reports_as=tuple(qualified_node_name(robot, spec.executable)
                                             for robot in robots))
              if spec.executable == 'tracker_node' else spec for spec in shared]
    return [*shared, *(in_namespace(spec, robot, statuses) for robot in robots for spec in kept
                       if spec.executable in ROBOT_NODE_NAMES)]


def streaming_cameras(options: GraphOptions) -> tuple[str, ...]:
    """The cameras whose images camera_node streams in this graph (none without it)."""
    if 'camera_node' not in {spec.executable for spec in graph_nodes(options)}:
        return ()
    return rendered_cameras(options.params_files, options.vision_overrides)


def rendered_cameras(params_files: tuple[Path, ...],
                     overrides: dict[str, object]) -> tuple[str, ...]:
    """The cameras camera_node renders with these params files and overrides."""
    values = node_parameters('camera_node', params_files, overrides)
    cameras = values.get('cameras', ['macro', 'micro'])
    return tuple(str(name) for name in cameras) if isinstance(cameras, (list, tuple)) else ()


def bench_cameras(options: GraphOptions) -> dict[str, str]:
    """The tracker's cameras that read a driver's images (``--camera external``), each with its
    image topic (``--image-topic``, or the tracker's params)."""
    if options.camera != 'external':
        return {}
    if options.image_topics:
        return dict(options.image_topics)
    values = node_parameters('tracker_node', options.params_files, {})
    cameras = values.get('cameras', ['macro', 'micro'])
    return {str(camera): str(values.get(f'{camera}.image_topic', f'/camera/{camera}/image_raw'))
            for camera in (cameras if isinstance(cameras, list) else [])}


def tracked_cameras(options: GraphOptions) -> tuple[str, ...]:
    """The cameras whose captures this graph publishes: vision_node's two, or the tracker's."""
    names = {spec.executable for spec in graph_nodes(options)}
    if 'vision_node' in names or 'tracker_node' not in names:
        return tuple(CAPTURE_TOPICS)
    if options.image_topics:
        return tuple(sorted(options.image_topics))
    cameras = node_parameters('tracker_node', options.params_files, {}).get(
        'cameras', list(CAPTURE_TOPICS))
    return tuple(str(name) for name in cameras) if isinstance(cameras, list) else ()


def check_camera_faults(vision_overrides: dict[str, object], vision: str) -> None:
    """Raises UsageError for camera faults (``faults.*`` of ``vision_overrides``) on a vision
    other than vision_node's, which injects them."""
    faults = sorted(name for name in vision_overrides if name.startswith('faults.'))
    if faults and vision != 'model':
        raise UsageError(f'fault injection ({", ".join(faults)}) is vision_node\'s: it needs '
                         f'--vision model, got --vision {vision}')


def check_record_images(record_images: bool, record: Path | None, vision: str,
                        camera: str) -> None:
    """Raises UsageError for ``record_images`` without a bag or images to record (rendered
    ``vision`` or an external ``camera``)."""
    if record_images and (record is None or (vision != 'images' and camera != 'external')):
        raise UsageError('--record-images needs --record BAG and images to record: --vision '
                         'images or --camera external')


def check_respawn(options: GraphOptions) -> None:
    """Raises UsageError for ``respawn`` with ``composed``: one robot's nodes or several's."""
    if options.composed and options.respawn:
        raise UsageError('--respawn restarts a crashed node in a process of its own; with '
                         '--composed the loop shares one process: choose one of them')


def check_graph(options: GraphOptions) -> None:
    """Raises UsageError for a graph that cannot be, one robot's or several's, naming what to
    leave out (a fleet on the bench is checked for what real robots cannot do besides:
    fleet_bench.check_bench)."""
    loop = graph_nodes(options)
    for name, source in (('camera', options.camera), ('robot', options.robot)):
        if source not in SOURCES:
            raise UsageError(f'{name} must be one of {list(SOURCES)}, got {source!r}')
    if options.external and options.composed:
        raise UsageError('--composed runs the lockstep faster than real time; with an external '
                         'camera or robot the graph runs at real time: leave --composed out')
    if options.open_loop_s is not None and servo_mode(options):
        raise UsageError('--open-loop makes one move without feedback and the servo mode corrects '
                         'every move: leave one of them out')
    if options.open_loop_s is not None and options.controller_overrides.get('open_loop_to_goal'):
        raise UsageError('--open-loop S makes one move of S seconds and --controller open-loop '
                         'one of the time to the goal: leave one of them out')
    if publishes_in_motion(options) and not any(spec.executable in ('vision_node', 'tracker_node')
                                              for spec in loop):
        raise UsageError('--captures-in-motion: vision_node or tracker_node publishes captures '
                         'in motion, and this graph has neither')
    check_respawn(options)
    check_camera_faults(options.vision_overrides, options.vision)
    check_record_images(options.record_images, options.record, options.vision, options.camera)


def all_specs(options: GraphOptions) -> list[NodeSpec]:
    """Every process of the graph: the simulation's, each robot's (in containers with
    ``composed``), then who listens (recorder, viewer).

    Raises
    ------
    UsageError
        A graph that cannot be (:func:`check_graph`).
    """
    check_graph(options)
    loop = graph_nodes(options)
    robots = robot_names(options)
    if options.markers:
        loop = with_markers(loop, robots)
    specs = list(loop)
    if options.composed:
        # Each robot's markers_node joins its robot's nodes in the containers from two robots
        # on, as the containers take one per core from there (42 processes of their own would
        # cost more than they give); a single robot's stays a process of its own, beside its
        # one container on another core (49x real time against 42x hosted, on 2 cores).
        apart = [spec for spec in loop if spec.executable == 'markers_node'] \
            if len(robots) == 1 else []
        specs = [*composed([spec for spec in loop if spec not in apart], options.containers),
                 *apart]
    if options.record is not None:
        specs.append(recorder_of_graph(options, options.record))
    if options.view is not None:
        specs.append(viewer_spec(*options.view, options.markers,
                                 robots if options.fleet else ()))
    return specs


def with_markers(loop: list[NodeSpec], robots: list[str]) -> list[NodeSpec]:
    """``loop`` with each robot's markers_node after the last of its nodes."""
    nodes = list(loop)
    for robot in robots:
        own = [k for k, spec in enumerate(nodes) if spec.namespace == robot]
        nodes.insert(own[-1] + 1 if own else len(nodes), in_namespace(MARKERS_NODE, robot))
    return nodes


def camera_node_of(options: GraphOptions) -> str:
    """The node whose camera parameters this graph uses: vision_node, or camera_node alone."""
    names = {spec.executable for spec in graph_nodes(options)}
    return 'camera_node' if 'camera_node' in names and 'vision_node' not in names \
        else 'vision_node'


def recorder_of_graph(options: GraphOptions, bag: Path) -> NodeSpec:
    """The recorder of ``run --record``: what this graph publishes, on its clock (a real robot's
    run: the system clock), the images with ``record_images`` (the rendered cameras', or a
    camera driver's).

    Raises
    ------
    UsageError
        ``record_images`` with no camera streaming images in this graph.
    """
    images = streaming_cameras(options) if options.record_images else ()
    driver_images = tuple(bench_cameras(options).values()) if options.record_images else ()
    if options.record_images and not images and not driver_images:
        raise UsageError('--record-images needs the rendered cameras (--vision images) or a '
                         'camera driver (--camera external)')
    loop = graph_nodes(options)
    # /camera/status is vision_node's (the tracker says why per camera, not recorded); a real
    # robot's driver publishes its wheels, not the simulation's clock, pose or slip; a tracker
    # publishes the captures of its own cameras only.
    unpublished: tuple[str, ...] = (
        () if any(spec.executable == 'vision_node' for spec in loop) else (CAMERA_STATUS_TOPIC,))
    if options.robot == 'external':
        unpublished += (CLOCK_TOPIC, ODOM_TOPIC, WHEEL_SLIP_TOPIC)
    cameras = tracked_cameras(options)
    unpublished += tuple(topic for name in CAPTURE_TOPICS if name not in cameras
                         for topic in (CAPTURE_TOPICS[name], CAPTURE_COVARIANCE_TOPICS[name]))
    topics = recorded_topics(robot_names(options), markers=options.markers, without=unpublished,
                             in_motion=robots_in_motion(options), cameras=cameras,
                             images=images)
    if guarded(options):
        topics.append(FLEET_GUARD_TOPIC)
    spec = recorder_spec(bag, options.storage, topics, frames=bool(images),
                         whole=options.record_whole or guarded(options))
    overrides = dict(spec.overrides)
    if driver_images:
        overrides.update(driver_images=list(driver_images))
    if options.external:
        overrides.update(lockstep_ticks=False)   # with a device, nothing runs in lockstep
    if options.robot == 'external':
        overrides.update(log_clock='wall')   # a real robot has no /clock
    return replace(spec, overrides=overrides)
