"""How a robot's nodes live in its namespace when the graph has several robots: one
dynamics_node simulates them all on one clock (and, on rendered images, one camera_node and one
tracker_node see them all), while each robot ``robot_k`` has its own vision_node,
controller_node and markers_node under ``/robot_k``. A single robot is the fleet of one in the
root namespace, where its nodes stay as they are. Who a graph's robots are: their namespaces,
their controller modes, whose captures in motion are published, and whether a guard keeps them
apart.

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

from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_bringup.params_files import node_parameters
from omni_micro_common.params import load_params_file
from omni_micro_common.topic_names import ROBOT_TOPICS, namespaced_topic, robot_name
from omni_micro_control.servo_config import SERVO_MODE

# A robot's own nodes: the rest of the graph (the simulation, the cameras a fleet shares, the
# recorder, the view) serves every robot.
ROBOT_NODE_NAMES = ('vision_node', 'controller_node', 'markers_node')


def in_namespace(spec: NodeSpec, robot: str, shared: tuple[str, ...] = ()) -> NodeSpec:
    """``spec``, a single robot's node, as robot ``robot``'s (its namespace; ``''``, the root
    one, leaves it as it is): its own topics remapped there (ROBOT_TOPICS, but those
    ``shared``: a shared node's)."""
    if not robot:
        return spec
    return replace(spec, namespace=robot, remaps=(
        f'__ns:=/{robot}', *(f'{topic}:={namespaced_topic(robot, topic)}'
                             for topic in ROBOT_TOPICS if topic not in shared)))


def namespaced_params(sources: list[Path], robot: str, folder: Path) -> list[Path]:
    """Each params file with its robot nodes' sections renamed ``/<robot>/<node>``, written in
    ``folder`` (the run's log folder)."""
    written = []
    for number, source in enumerate(sources):
        sections = load_params_file(source)
        renamed = {f'/{robot}/{node}': {'ros__parameters': values}
                   for node, values in sections.items() if node in ROBOT_NODE_NAMES}
        path = folder / f'{robot}.params.{number}.yaml'
        path.write_text(yaml.safe_dump(renamed, sort_keys=False))
        written.append(path)
    return written


def robot_names(options: GraphOptions) -> list[str]:
    """The robots' namespaces: a fleet's ``robot_k``, or the root one (``''``) of a single
    robot."""
    if options.fleet is None:
        return ['']
    return [robot_name(k) for k in range(len(options.fleet.plan.starts_m))]


def robot_modes(options: GraphOptions) -> list[str]:
    """Each robot's controller mode as its controller_node will have it: a single robot's as
    the params files and overrides say; a fleet robot's as its robots file says, else
    (``paper``) the params files' (a ``controller_node:`` section sets every robot's)."""
    if options.fleet is None:
        return [str(node_parameters('controller_node', options.params_files,
                                    options.controller_overrides).get('mode', 'paper'))]
    configured = str(node_parameters('controller_node', options.params_files,
                                     {}).get('mode', 'paper'))
    return [mode if mode != 'paper' else configured for mode in options.fleet.controllers]


def guarded(options: GraphOptions) -> bool:
    """Whether the orchestration's guard keeps the robots apart: several real robots, which no
    dynamics_node sees touch (fleet_bench). It follows every robot's captures, in motion too,
    and its stops are recorded, as is what comes after the last goal's end (a stop, the robots
    coming to rest)."""
    return options.fleet is not None and options.external


def robots_in_motion(options: GraphOptions) -> list[str]:
    """The robots whose captures in motion the vision side publishes: asked, read by their
    servo, or followed by the guard."""
    return [robot for robot, mode in zip(robot_names(options), robot_modes(options), strict=True)
            if options.captures_in_motion or mode == SERVO_MODE or guarded(options)]
