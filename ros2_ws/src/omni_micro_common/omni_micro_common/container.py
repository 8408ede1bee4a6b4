"""Several nodes in one process, spun by one executor (``ros2 run omni_micro_common container``).

rclpy has no component container (rclcpp_components' ``component_container`` loads C++ nodes
only); this is the part of one that the graph needs. Each node is named by its module, which
holds a :class:`~omni_micro_common.node_runtime.NodeComponent` as ``COMPONENT`` (every
omni-micro node module does), and takes its own ROS arguments, ended by ``--``::

    container omni_micro_sim.dynamics_node --ros-args --params-file dyn.yaml -p paused:=true -- \\
              omni_micro_vision.vision_node --ros-args -p seed:=3 -- \\
              omni_micro_control.controller_node

What it buys: the messages between the hosted nodes stay in the process (Fast DDS delivers
within a process without a transport), and no wake-up of another process is needed per
message; the cost is that they share one core. Separate processes stay the default of a run:
a real camera or robot replaces one of them.
"""

from __future__ import annotations

import importlib
import sys

from omni_micro_common.node_runtime import Hosted, NodeComponent, run_components

USAGE = ('usage: container MODULE [--ros-args ARG... --] [MODULE [--ros-args ARG... --]]...\n'
         '  MODULE: a node module with a COMPONENT, e.g. omni_micro_sim.dynamics_node')


class ContainerUsageError(ValueError):
    """A container command line that does not say which nodes to run, or how."""


def parse_hosted(argv: list[str]) -> list[tuple[str, list[str]]]:
    """The (module, its ROS arguments) of a container's command line, in order.

    Raises
    ------
    ContainerUsageError
        No module, an option where a module was expected, or ``--ros-args`` not ended by
        ``--`` before the next module.
    """
    hosted: list[tuple[str, list[str]]] = []
    index = 0
    while index < len(argv):
        module = argv[index]
        if module.startswith('-') or not module:
            raise ContainerUsageError(f'expected a node module (e.g. omni_micro_sim.dynamics_node)'
                                      f', got {module!r}')
        index += 1
        node_args: list[str] = []
        if index < len(argv) and argv[index] == '--ros-args':
            end = argv.index('--', index) if '--' in argv[index:] else len(argv)
            node_args = argv[index:end]
            index = end + 1
        hosted.append((module, node_args))
    if not hosted:
        raise ContainerUsageError('no node to run: name at least one node module')
    return hosted


def load_component(module_name: str) -> NodeComponent:
    """The ``COMPONENT`` of a node module.

    Raises
    ------
    ContainerUsageError
        The module is not installed, or holds no NodeComponent.
    """
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as error:
        if error.name and not module_name.startswith(error.name):
            raise ContainerUsageError(f'module {module_name!r} needs {error.name!r}, which is '
                                      f'not installed') from None
        raise ContainerUsageError(f'no module {module_name!r} is installed: expected a node '
                                  f'module such as omni_micro_sim.dynamics_node') from None
    component = getattr(module, 'COMPONENT', None)
    if not isinstance(component, NodeComponent):
        raise ContainerUsageError(f'module {module_name!r} has no COMPONENT: not a node module '
                                  f'(expected e.g. omni_micro_sim.dynamics_node)')
    return component


def main(args: list[str] | None = None) -> None:
    argv = list(sys.argv if args is None else args)
    if any(flag in argv[1:2] for flag in ('-h', '--help')):
        print(USAGE)
        return
    try:
        hosted = [Hosted(load_component(module), node_args or ['--ros-args'], label=module)
                  for module, node_args in parse_hosted(argv[1:])]
    except ContainerUsageError as error:
        print(f'container: {error}\n{USAGE}', file=sys.stderr)
        raise SystemExit(2) from None
    # The process's own arguments are the program's name only: each node has its own.
    run_components(hosted, args=argv[:1])


if __name__ == '__main__':
    main()
