"""Slip dynamics of the tri-wheeled omnidirectional microrobot of Jin, Chen and Li (ICIRA 2008).

The physics lives in plain modules (no rclpy import) so it can be used and tested without ROS:
:mod:`parameters` (the robot), :mod:`profile` (wheel speed commands), :mod:`kernels` (eqs. 1-13),
:mod:`simulator` (the stepping API and open-loop runs). :mod:`dynamics_node` is the ROS adapter.
"""

from omni_micro_sim.errors import CommandError, ParameterError, SimulationError
from omni_micro_sim.parameters import CantileverSide, MotorLimits, RobotParameters
from omni_micro_sim.profile import WheelSpeedProfile, move_profile
from omni_micro_sim.simulator import (
    OpenLoopResult,
    RobotState,
    SlipSimulator,
    simulate_open_loop,
    simulate_open_loop_batch,
)

__all__ = [
    'CantileverSide',
    'CommandError',
    'MotorLimits',
    'OpenLoopResult',
    'ParameterError',
    'RobotParameters',
    'RobotState',
    'SimulationError',
    'SlipSimulator',
    'WheelSpeedProfile',
    'move_profile',
    'simulate_open_loop',
    'simulate_open_loop_batch',
]
