"""The dynamics node's parameters, declared and checked: the one place that says which
parameters ``dynamics_node`` has (the graph's params file lists them with their defaults) and
what each becomes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, ParameterType
from rclpy.node import Node

from omni_micro_common.conventions import BASE_FRAME, ODOM_FRAME
from omni_micro_common.lockstep import DEFAULT_MAX_LEAD_S
from omni_micro_common.reader_matching import node_list_parameter
from omni_micro_sim import paper
from omni_micro_sim.errors import ParameterError
from omni_micro_sim.parameters import (
    DEFAULT_PERIOD_S,
    MotorLimits,
    RobotParameters,
    robot_parameter_values,
)
from omni_micro_sim.simulated_robots import check_namespaces

# Fixed at start-up: they define the robot, and changing them mid-run would change physics.
READ_ONLY = ParameterDescriptor(read_only=True)
# /wheel_slip, /odom_throttle and /joint_states_throttle at 10 Hz of simulated time by default
# (the grid is 50 Hz).
DEFAULT_SLIP_EVERY = 5
DEFAULT_THROTTLE_EVERY = 5
# Where stamps count from: 0, or the wall clock when time starts.
STAMP_ORIGINS = ('zero', 'wall')


def robot_defaults() -> dict[str, object]:
    # The paper's section 3.5.3 robot, so a node started without a params file simulates it.
    return robot_parameter_values(paper.FIG11_OPEN_LOOP.robot())


@dataclass(frozen=True)
class DynamicsParameters:
    robot: RobotParameters
    limits: MotorLimits
    period_s: float
    slip_every: int
    throttle_every: int
    initial_pose: list[float]
    odom_frame: str
    base_frame: str
    real_time_factor: float
    stamp_origin: str
    paused: bool
    lockstep_nodes: list[str]
    awaited_readers: dict[str, tuple[str, ...]]
    max_lead_s: float
    # Several robots on the one clock (a fleet): their namespaces, and each one's
    # start pose and true robot (its wheel offsets); none: the one robot above.
    robots: list[str] = field(default_factory=list)
    robot_poses: list[list[float]] = field(default_factory=list)
    robot_models: list[RobotParameters] = field(default_factory=list)


def declare_dynamics_parameters(node: Node) -> DynamicsParameters:
    """Declare every parameter of the dynamics on ``node`` and check them.

    Raises
    ------
    ParameterError
        Naming the parameter and what it must be.
    """
    robot_values = {name: node.declare_parameter(f'robot.{name}', default, READ_ONLY).value
                    for name, default in robot_defaults().items()}
    limit_values = {f.name: node.declare_parameter(f'motor.{f.name}',
                                                   getattr(MotorLimits(), f.name),
                                                   READ_ONLY).value
                    for f in fields(MotorLimits)}
    period = node.declare_parameter('publish_period_s', DEFAULT_PERIOD_S, READ_ONLY).value
    # Nothing in the loop reads the slip: one sample in this many ticks (1: every tick).
    slip_every = node.declare_parameter('wheel_slip_every', DEFAULT_SLIP_EVERY, READ_ONLY).value
    # Who only watches the robot reads /odom and /joint_states at this fraction of ticks.
    throttle_every = node.declare_parameter('throttle_every', DEFAULT_THROTTLE_EVERY,
                                            READ_ONLY).value
    for name, value in (('wheel_slip_every', slip_every),
                        ('throttle_every', throttle_every)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ParameterError(f'{name} must be a whole number of ticks >= 1, got '
                                 f'{value!r}')
    initial = node.declare_parameter('initial_pose', [0.0, 0.0, 0.0], READ_ONLY).value
    odom_frame = node.declare_parameter('odom_frame', ODOM_FRAME, READ_ONLY).value
    base_frame = node.declare_parameter('base_frame', BASE_FRAME, READ_ONLY).value
    real_time_factor = checked_rtf(node.declare_parameter('real_time_factor', 1.0).value)
    stamp_origin = node.declare_parameter('stamp_origin', 'zero', READ_ONLY).value
    if stamp_origin not in STAMP_ORIGINS:
        raise ParameterError(f'stamp_origin must be one of {list(STAMP_ORIGINS)}, got '
                             f'{stamp_origin!r}')
    if stamp_origin == 'wall' and real_time_factor != 1.0:
        raise ParameterError(f'stamp_origin wall needs real_time_factor 1 (the wall clock '
                             f'runs at 1), got {real_time_factor!r}')
    paused = bool(node.declare_parameter('paused', False).value)
    # An empty list ([] in YAML or -p) reaches rclpy as no value at all: nobody takes part.
    lockstep_nodes = node_list_parameter(node, 'lockstep_nodes')
    # The readers time waits for at its start, by node (dynamics_node's docstring).
    awaited = awaited_readers(node_list_parameter(node, 'awaited_readers'))
    max_lead_s = node.declare_parameter('lockstep_max_lead_s', DEFAULT_MAX_LEAD_S,
                                        READ_ONLY).value
    if len(initial) != 3:
        raise ParameterError(f'initial_pose must be [x_m, y_m, phi_rad], got {list(initial)}')
    robot_values['wheel_offsets_rad'] = tuple(robot_values['wheel_offsets_rad'])
    robot_values['center_of_mass_m'] = tuple(robot_values['center_of_mass_m'])
    robot = RobotParameters.from_mapping(robot_values)
    robots = node_list_parameter(node, 'robots')
    check_namespaces(robots)
    poses = _per_robot(node, 'robot_poses', robots, [0.0, 0.0, 0.0])
    offsets = _per_robot(node, 'robot_wheel_offsets_rad', robots,
                         list(robot.wheel_offsets_rad))
    return DynamicsParameters(
        robot, MotorLimits(**limit_values), period,
        slip_every, throttle_every, list(initial), odom_frame, base_frame, real_time_factor,
        stamp_origin, paused, lockstep_nodes, awaited, max_lead_s, robots, poses,
        [replace(robot, wheel_offsets_rad=(a, b, c)) for a, b, c in offsets])


def _per_robot(node: Node, name: str, robots: list[str],
               default: list[float]) -> list[list[float]]:
    """Three numbers per robot, flat (ROS has no nested arrays); empty: ``default`` each."""
    descriptor = ParameterDescriptor(read_only=True, type=ParameterType.PARAMETER_DOUBLE_ARRAY)
    values = list(node.declare_parameter(name, [0.0], descriptor).value or [])
    if values == [0.0] or not robots:
        values = []
    if not values:
        return [list(default) for _ in robots]
    if len(values) != 3 * len(robots) or not all(math.isfinite(v) for v in values):
        raise ParameterError(f'{name}: 3 finite numbers for each of the {len(robots)} robots '
                             f'({3 * len(robots)}), got {values}')
    return [values[3 * k:3 * k + 3] for k in range(len(robots))]


def checked_rtf(value: Any) -> float:
    try:
        rtf = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f'real_time_factor must be a number, got {value!r}') from None
    if math.isnan(rtf) or rtf <= 0.0:
        raise ParameterError(f'real_time_factor must be a number > 0 (.inf: as fast as the '
                             f'lockstep allows), got {value!r}')
    return rtf


def awaited_readers(entries: list[str]) -> dict[str, tuple[str, ...]]:
    """``['markers_node:/odom_throttle', 'markers_node:/wheel_slip']`` -> topics by node.

    Raises
    ------
    ParameterError
        An entry that is not NODE:/TOPIC, named.
    """
    readers: dict[str, tuple[str, ...]] = {}
    for entry in entries:
        node, _, topic = entry.partition(':')
        if not node or not topic.startswith('/'):
            raise ParameterError(f'awaited_readers: each entry must be NODE:/TOPIC, got {entry!r}')
        readers[node] = (*readers.get(node, ()), topic)
    return readers
