"""What a fleet's graph starts: one dynamics_node simulating every robot on one clock,
per robot ``robot_k`` its vision_node and controller_node (and, drawing it, its markers_node) in
the namespace ``/robot_k``, and the recorder of every robot's topics; all but the recorder in
one process when composed. On rendered images, one camera_node and one tracker_node for all in
place of the vision_nodes: the robots share the cameras, and the tracker
tells them apart by the codes the camera draws.

One dynamics process for all (not one per robot): the robots share one ``/clock`` and one
lockstep, which one process owning time gives by construction; N processes would each need a
clock of their own and a protocol to keep them level. A robot's nodes are the single robot's,
unchanged: their topics, absolute in the code (``/odom``), are remapped into the namespace
(``/robot_k/odom``), their sections of the params files read as ``/robot_k/<node>`` (ROS matches
a bare section name only in the root namespace), and they report on the one ``/lockstep`` as
``robot_k/<node>`` (:mod:`omni_micro_common.lockstep_groups`).
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import yaml

from omni_micro_bringup.composition import (
    ORCHESTRATOR_NODE,
    RECORDER_NODE,
    awaited_readers,
    lockstep_nodes,
    recorded_topics,
    recorder_spec,
    rendered_cameras,
    viewer_spec,
)
from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.node_overrides import (
    capture_uncertainty_of,
    captures_read_by,
    markers_told,
    rendered_motion,
    servo_timing_of,
)
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_bringup.node_spec import composed as composed_loop
from omni_micro_bringup.params_files import (
    graph_params_file,
    node_parameters,
)
from omni_micro_common.lockstep_groups import qualified_node_name
from omni_micro_common.params import load_params_file
from omni_micro_common.topic_names import (
    CAMERA_STATUS_TOPIC,
    ODOM_THROTTLE_TOPIC,
    ROBOT_TOPICS,
    robot_name,
    robot_topic,
)
from omni_micro_control.fleet_files import controller_settings
from omni_micro_control.servo_config import SERVO_MODE
from omni_micro_sim.parameters import RobotParameters
from omni_micro_vision.scene import FLEET_COLOURS

# A robot's nodes, each with its package; and, drawing it on /robot_k/markers, its markers_node.
ROBOT_NODES = (('omni_micro_vision', 'vision_node'), ('omni_micro_control', 'controller_node'))
MARKERS_NODE = ('omni_micro_vision', 'markers_node')
# With rendered images: the cameras and the tracker every robot shares.
CAMERA_NODE, TRACKER_NODE = ('omni_micro_vision', 'camera_node'), ('omni_micro_vision',
                                                                    'tracker_node')


def namespaced_params(sources: list[Path], robot: str, folder: Path) -> list[Path]:
    """Each params file with its robot nodes' sections renamed ``/<robot>/<node>``, written in
    ``folder`` (the run's log folder)."""
    written = []
    for number, source in enumerate(sources):
        sections = load_params_file(source)
        renamed = {f'/{robot}/{node}': {'ros__parameters': values}
                   for node, values in sections.items()
                   if node in {name for _, name in (*ROBOT_NODES, MARKERS_NODE)}}
        path = folder / f'{robot}.params.{number}.yaml'
        path.write_text(yaml.safe_dump(renamed, sort_keys=False))
        written.append(path)
    return written


def controller_modes(modes: list[str], params_files: tuple[Path, ...]) -> list[str]:
    """Each robot's controller mode as its node will have it: the one given, else (``paper``)
    the params files' (a ``controller_node:`` section sets every robot's)."""
    return [str(node_parameters('controller_node', params_files,
                                {'mode': mode} if mode != 'paper' else {}).get('mode', 'paper'))
            for mode in modes]


def check_vision(vision: str) -> None:
    """Raises UsageError if ``vision`` is not one known."""
    if vision not in ('model', 'images'):
        raise UsageError(f"vision must be 'model' or 'images', got {vision!r}")


def shared_cameras(count: int, seed: int, params: list[Path],
                   capture_readers: list[str], recorded: bool = False,
                   in_motion: bool = False,
                   capture_uncertainty: object = 'covariance') -> list[NodeSpec]:
    """The camera pair a fleet shares: camera_node rendering every robot with its
    code, its frames read reliably by tracker_node, which names each robot and publishes its
    captures under its namespace to the robot's ``capture_readers`` (node names: on the topics
    the controllers' ``capture_uncertainty`` reads), and with ``in_motion`` its captures in
    motion (a servo's: placed in the blur of camera_node's frames as their exposure makes it,
    as for one robot); with ``recorded``, the recorder reads the frames too, and the first
    waits for it as well."""
    robots = [robot_name(k) for k in range(count)]
    camera: dict[str, object] = {'seed': int(seed), 'robots': robots,
                                 'image_readers': [TRACKER_NODE[1],
                                                   *((RECORDER_NODE,) if recorded else ())]}
    tracker: dict[str, object] = {
        'robots': robots, 'image_reliability': 'reliable',
        **captures_read_by([f'{robot}/{name}' for robot in robots for name in capture_readers],
                           recorded=False, capture_uncertainty=capture_uncertainty),
        **({'captures_in_motion': True, **rendered_motion(tuple(params), {})} if in_motion
           else {})}
    # The tracker takes part in each robot's lockstep as that robot's (it gates its captures).
    return [NodeSpec(*CAMERA_NODE, params=tuple(params), overrides=camera),
            NodeSpec(*TRACKER_NODE, params=tuple(params), overrides=tracker,
                     reports_as=tuple(qualified_node_name(robot, TRACKER_NODE[1])
                                      for robot in robots))]


def fleet_specs(starts_m: list[tuple[float, float]], robots: list[RobotParameters], seed: int,
                real_time_factor: float, params_files: tuple[Path, ...],
                folder: Path, record: tuple[Path, str] | None = None,
                composed: bool = False, containers: int | None = None,
                markers: bool = False,
                view: tuple[str, int] | None = None,
                controllers: list[str] | None = None, vision: str = 'model',
                vision_overrides: dict[str, object] | None = None,
                record_images: bool = False) -> list[NodeSpec]:
    """The processes of a fleet's graph: dynamics for all, each robot's two nodes (with
    ``markers`` its markers_node too, the robot in its colour and labelled), with ``record``
    (the bag, its storage) the recorder of every robot's topics, and with ``view`` (host, port)
    the live view of every robot's. ``controllers``: robot k's controller mode (``paper``, the
    default, leaves it to the params files); a servo's vision_node (or the shared tracker)
    publishes the captures in motion it reads. ``vision``: ``model``, each robot its
    vision_node; ``images``, one camera_node rendering every robot with its code and one
    tracker_node naming them, in place of the vision_nodes (the cameras a fleet shares);
    ``vision_overrides`` (the camera faults) set on every robot's vision_node;
    ``record_images``: the recorder keeps the shared cameras' images too. ``composed``: dynamics
    and every robot's nodes in ``containers`` processes (omni_micro_common's container: one hosts
    them all, more share them as :func:`~omni_micro_bringup.node_spec.composed` says), each node
    with the same arguments as on its own; the recorder and the view stay processes of their own,
    as a single robot's.
    """
    shipped = (graph_params_file(), *params_files)
    count = len(starts_m)
    modes = controller_modes(controllers or ['paper'] * count, params_files)
    servos = tuple(k for k in range(count) if modes[k] == SERVO_MODE)
    images = vision == 'images'
    check_vision(vision)
    # Which captures the controllers read (bare, or with their covariance): the cameras wait
    # for those readers there.
    uncertainty = capture_uncertainty_of(params_files, {})
    # What every robot's markers_node is told as a single robot's is (the same for all: a
    # robot's own controller settings are its mode alone).
    drawn_as_one = markers_told(params_files, CAMERA_NODE[1] if images else 'vision_node',
                                vision_overrides or {}, {}, {})
    nodes = (*(ROBOT_NODES[1:] if images else ROBOT_NODES), *((MARKERS_NODE,) if markers else ()))
    names = [robot_name(k) for k in range(count)]
    streamed = rendered_cameras(params_files, {}) if images and record_images else ()
    recorder = None if record is None else recorder_spec(*record, recorded_topics(
        names, markers, (CAMERA_STATUS_TOPIC,) if images else (),
        in_motion=[names[k] for k in servos], images=streamed), frames=bool(streamed))
    dynamics = {
        'paused': True, 'real_time_factor': float(real_time_factor),
        'robots': names,
        'robot_poses': [float(v) for x, y in starts_m for v in (x, y, 0.0)],
        'robot_wheel_offsets_rad': [float(v) for robot in robots
                                    for v in robot.wheel_offsets_rad]}
    specs = [NodeSpec('omni_micro_sim', 'dynamics_node', params=shipped, overrides=dynamics)]
    if images:
        specs += shared_cameras(count, seed, list(shipped), [name for _, name in nodes],
                                recorded=bool(streamed) and recorder is not None,
                                in_motion=bool(servos), capture_uncertainty=uncertainty)
    for k in range(count):
        robot = robot_name(k)
        params = tuple(namespaced_params(list(shipped), robot, folder))
        servo = k in servos
        own: dict[str, dict[str, object]] = {'vision_node': {
                   # Each robot's captures their own noise, as the fleet twin draws it.
                   'seed': int(seed) * 1000 + k,
                   **captures_read_by([f'{robot}/{name}' for _, name in nodes
                                       if name != 'vision_node'],
                                      recorded=False, capture_uncertainty=uncertainty),
                   **({'captures_in_motion': True} if servo else {}),
                   **(vision_overrides or {})},
               'controller_node': {'goal_time': 'stamp', **controller_settings(modes[k]),
                                   # Its first move waits for the readers that must have it.
                                   'trajectory_readers': [
                                       'dynamics_node',
                                       *((f'{robot}/markers_node',) if markers else ()),
                                       *((RECORDER_NODE,) if recorder else ())],
                                   **(servo_timing_of(params_files, CAMERA_NODE[1] if images
                                                      else 'vision_node') if servo else {})},
               'markers_node': {
                   **drawn_as_one,
                   'robot.wheel_offsets_rad': [float(v) for v in robots[k].wheel_offsets_rad],
                   'robot.colour': list(FLEET_COLOURS[k % len(FLEET_COLOURS)]),
                   'robot.label': robot,
                   # Its first array waits for the recorder's reader, which must not miss it.
                   'markers_readers': [RECORDER_NODE] if recorder else []}}
        for package, node in nodes:
            specs.append(robot_node(k, package, node, own[node], params))
    listeners = [replace(spec, params=shipped) for spec in (
        *(() if recorder is None else (recorder,)),
        *(() if view is None else (viewer_spec(*view, markers, names),)))]
    # Time waits for every node's reports (the orchestration's as each robot's coordinator:
    # fleet_graph) and for the readers that must have every robot's streams from the first.
    specs[0] = replace(specs[0], overrides={
        **dynamics,
        'lockstep_nodes': lockstep_nodes([*specs, *listeners],
                                         [coordinator_name(k) for k in range(count)]),
        'awaited_readers': awaited_readers([*specs, *listeners], names, ODOM_THROTTLE_TOPIC)})
    return [*(composed_loop(specs, containers) if composed else specs), *listeners]


def robot_node(robot: int, package: str, executable: str, overrides: dict[str, object],
               params: tuple[Path, ...], shared: tuple[str, ...] = ()) -> NodeSpec:
    """Robot ``robot``'s node of the single robot's ``executable``, in its namespace, its own
    topics remapped there (ROBOT_TOPICS, but those ``shared``: a shared node's)."""
    return NodeSpec(package, executable, overrides, namespace=robot_name(robot),
                    remaps=(f'__ns:=/{robot_name(robot)}',
                            *(f'{topic}:={robot_topic(robot, topic)}' for topic in ROBOT_TOPICS
                              if topic not in shared)),
                    params=params)


def coordinator_name(robot: int) -> str:
    """How the orchestration reports on /lockstep as robot ``robot``'s coordinator."""
    return qualified_node_name(robot_name(robot), ORCHESTRATOR_NODE)
