"""Slip dynamics of the tri-wheeled omnidirectional microrobot of Jin, Chen and Li (ICIRA 2008).

The physics lives in plain modules (no rclpy import) so it can be used and tested without ROS:
:mod:`parameters` (the robot), :mod:`state` (its pose and velocity), :mod:`profile` (wheel
commands), :mod:`steering` (the steering motion) and :mod:`knots` (both between knots, plain
Python), :mod:`kernels` (eqs. 1-13, numba), :mod:`integrator` (RK4 through the knots, numba),
:mod:`simulator` (the stepping API), :mod:`open_loop` (moves from rest, single and batched),
:mod:`stepper` (the grid the node publishes on), :mod:`wheel_trajectory` (the wheel command
contract), :mod:`paper` (the paper's scenarios and numbers), :mod:`reference` (a solve_ivp check of
the integrator), :mod:`errors`. :mod:`dynamics_node` is the ROS adapter, :mod:`dynamics_parameters`
its parameters, :mod:`simulated_robots` the robots it simulates on its clock (one, or a
fleet's, each under its namespace).

The names below load on first use (PEP 562), so that importing a light module of this package
(parameters, state, profile) does not compile the slip kernels.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:   # what the names are, for type checkers; at run time __getattr__ loads them
    from omni_micro_sim.errors import CommandError, ParameterError, SimulationError
    from omni_micro_sim.open_loop import (
        OpenLoopResult,
        simulate_open_loop,
        simulate_open_loop_batch,
    )
    from omni_micro_sim.parameters import CantileverSide, MotorLimits, RobotParameters
    from omni_micro_sim.profile import WheelSpeedProfile, move_profile
    from omni_micro_sim.simulator import SlipSimulator
    from omni_micro_sim.state import RobotState

_EXPORTS = {
    'CantileverSide': 'omni_micro_sim.parameters',
    'CommandError': 'omni_micro_sim.errors',
    'MotorLimits': 'omni_micro_sim.parameters',
    'OpenLoopResult': 'omni_micro_sim.open_loop',
    'ParameterError': 'omni_micro_sim.errors',
    'RobotParameters': 'omni_micro_sim.parameters',
    'RobotState': 'omni_micro_sim.state',
    'SimulationError': 'omni_micro_sim.errors',
    'SlipSimulator': 'omni_micro_sim.simulator',
    'WheelSpeedProfile': 'omni_micro_sim.profile',
    'move_profile': 'omni_micro_sim.profile',
    'simulate_open_loop': 'omni_micro_sim.open_loop',
    'simulate_open_loop_batch': 'omni_micro_sim.open_loop',
}

__all__ = [
    'CantileverSide', 'CommandError', 'MotorLimits', 'OpenLoopResult', 'ParameterError',
    'RobotParameters', 'RobotState', 'SimulationError', 'SlipSimulator', 'WheelSpeedProfile',
    'move_profile', 'simulate_open_loop', 'simulate_open_loop_batch',
]
assert sorted(__all__) == sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    if name not in _EXPORTS:
        raise AttributeError(f'module {__name__!r} has no attribute {name!r}')
    return getattr(importlib.import_module(_EXPORTS[name]), name)
