"""One node process of a graph: what it runs (an installed node, the container hosting several,
or a command given in its place), in which namespace, with which remaps, params files and
overrides; and its command line, the same for a single robot's node and a fleet's."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from omni_micro_bringup.errors import UsageError
from omni_micro_bringup.params_files import format_parameter, resolve_executable
from omni_micro_common.lockstep_groups import qualified_node_name

# Nodes that report to the dynamics in lockstep (a stand-in started by command does not);
# markers_node as a watcher (omni_micro_common.lockstep), so that /markers is the same every run.
LOCKSTEP_NODES = ('vision_node', 'camera_node', 'tracker_node', 'controller_node',
                  'markers_node')
# Nodes restarted when they crash, with --respawn (a robot's own: the others' deaths end the run).
RESPAWNABLE_NODES = ('vision_node', 'controller_node')
# The process that hosts the loop's nodes with --composed (its log is <name>.log); with several,
# the others are loop_container_1, loop_container_2, ...
LOOP_CONTAINER = 'loop_container'
# The simulation's own nodes: with several containers, the first hosts them and the others the
# robots' nodes. Their work grows with every robot's every step, about as much as all the robots'
# nodes together (dynamics_node: each robot's tick, and each node's lockstep report, read).
SIMULATION_NODES = ('dynamics_node', 'camera_node')


@dataclass(frozen=True)
class NodeSpec:
    """One node process: its package, executable and parameter overrides."""

    package: str
    executable: str
    overrides: dict[str, object] = field(default_factory=dict)
    # A command line that replaces the installed entry point (e.g. a stand-in camera driver).
    command: tuple[str, ...] | None = None
    respawn: bool = False
    # A command that reports on /lockstep all the same (the recorder keeping every frame).
    lockstep: bool = False
    # The nodes this process hosts, for omni_micro_common's container (the loop in one process).
    hosts: tuple[NodeSpec, ...] = ()
    # A robot's namespace in a fleet's graph (omni_micro_bringup.robot_namespaces).
    namespace: str = ''
    # Its topics' remaps (``/odom:=/robot_1/odom``) and its params files, in order (later files
    # win): what its command line says before the overrides.
    remaps: tuple[str, ...] = ()
    params: tuple[Path, ...] = ()
    # The names it reports under on /lockstep when not its own: the tracker a fleet's
    # robots share reports once per robot, as that robot's (``robot_1/tracker_node``).
    reports_as: tuple[str, ...] = ()
    # Which of the loop's containers this one is (0: the first, or the only one).
    container: int = 0

    @property
    def name(self) -> str:
        """The process's name (its log is <name>.log): ``robot_1.controller_node`` in a
        robot's namespace."""
        if self.hosts:
            return f'{LOOP_CONTAINER}_{self.container}' if self.container else LOOP_CONTAINER
        return f'{self.namespace}.{self.executable}' if self.namespace else self.executable

    @property
    def respawnable(self) -> bool:
        """A robot's own node, restarted when it crashes with --respawn."""
        return not self.hosts and self.executable in RESPAWNABLE_NODES

    @property
    def reports_lockstep(self) -> bool:
        return self.lockstep or (self.command is None and self.executable in LOCKSTEP_NODES)

    @property
    def lockstep_names(self) -> tuple[str, ...]:
        """The nodes of this process that report on /lockstep, as each names itself
        (``robot_1/controller_node`` in a robot's namespace)."""
        if self.hosts:
            return tuple(name for spec in self.hosts for name in spec.lockstep_names)
        if not self.reports_lockstep:
            return ()
        return self.reports_as or (qualified_node_name(self.namespace, self.executable),)


def composed(specs: list[NodeSpec], containers: int | None = None) -> list[NodeSpec]:
    """The nodes of ``specs`` in ``containers`` processes of omni_micro_common's container.

    One hosts them all. With more, the first hosts the simulation's nodes
    (:data:`SIMULATION_NODES`) and the others the rest, namespace by namespace (a robot's nodes
    stay together), in contiguous blocks of as equal a count as may be; never more containers
    than there are blocks to fill them. None: one per core this process may use when there are
    two blocks or more (robots, or a fleet's shared tracker), else one. Measured on 2 cores
    (docs/fleet.md, "The graph at scale"): 1.02-1.4x as fast as one container from 2 to 16
    robots, about even at 42 (0.67x real time against 0.70x), and about 10 % slower for one
    robot, whose two nodes do too little to pay for the messages between processes.

    Raises
    ------
    UsageError
        A node given as a command (a stand-in driver): the container hosts installed nodes; or
        fewer than one container.
    """
    commands = [spec.name for spec in specs if spec.command is not None]
    if commands:
        raise UsageError(f'--composed hosts installed nodes only, not the command of '
                         f'{", ".join(commands)}: run them as separate processes')
    if containers is not None and containers < 1:
        raise UsageError(f'--composed: expected 1 container or more, got {containers}')
    simulation = [spec for spec in specs if spec.executable in SIMULATION_NODES]
    namespaces: dict[str, list[NodeSpec]] = {}
    for spec in specs:
        if spec.executable not in SIMULATION_NODES:
            namespaces.setdefault(spec.namespace, []).append(spec)
    blocks = list(namespaces.values())
    if containers is None:
        containers = len(os.sched_getaffinity(0)) if len(blocks) >= 2 else 1
    if containers == 1 or not simulation or not blocks:
        return [NodeSpec('omni_micro_common', 'container', hosts=tuple(specs))]
    shares = min(containers - 1, len(blocks))
    groups = [simulation] + [
        [spec for block in blocks[len(blocks) * k // shares:len(blocks) * (k + 1) // shares]
         for spec in block] for k in range(shares)]
    return [NodeSpec('omni_micro_common', 'container', hosts=tuple(group), container=number)
            for number, group in enumerate(groups)]


def process_argv(spec: NodeSpec) -> list[str]:
    """The command line of a node's process: its entry point and ROS arguments; for the
    container, each hosted node's module and its own ROS arguments up to ``--``."""
    if spec.command is not None:
        return list(spec.command)
    executable = str(resolve_executable(spec.package, spec.executable))
    if spec.hosts:
        return [executable, *(word for hosted in spec.hosts for word in (
            f'{hosted.package}.{hosted.executable}', *ros_arguments(hosted), '--'))]
    return [executable, *ros_arguments(spec)]


def ros_arguments(spec: NodeSpec) -> list[str]:
    argv = ['--ros-args']
    for rule in spec.remaps:
        argv += ['-r', rule]
    for path in spec.params:
        argv += ['--params-file', str(path)]
    for name, value in spec.overrides.items():
        argv += ['-p', f'{name}:={format_parameter(value)}']
    return argv
