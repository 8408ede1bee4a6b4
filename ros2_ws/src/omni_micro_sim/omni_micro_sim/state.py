"""The robot's planar state: pose and velocity in the platform frame, SI units.

Kept apart from the simulator so that what only needs a pose (the cameras' renderer, the
markers) does not load the slip kernels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from omni_micro_sim.errors import SimulationError
from omni_micro_sim.parameters import require_finite


@dataclass(frozen=True)
class RobotState:
    """Pose and velocity in the inertial (platform) frame, SI units."""

    x_m: float = 0.0
    y_m: float = 0.0
    phi_rad: float = 0.0
    vx_m_s: float = 0.0
    vy_m_s: float = 0.0
    omega_rad_s: float = 0.0

    def __post_init__(self) -> None:
        values = (self.x_m, self.y_m, self.phi_rad, self.vx_m_s, self.vy_m_s, self.omega_rad_s)
        # The simulator builds two states per tick from floats: check those in one pass.
        if all(type(value) is float and math.isfinite(value) for value in values):
            return
        for name in ('x_m', 'y_m', 'phi_rad', 'vx_m_s', 'vy_m_s', 'omega_rad_s'):
            try:
                object.__setattr__(self, name, require_finite(name, getattr(self, name)))
            except ValueError as error:
                raise SimulationError(f'robot state: {error}') from None

    def as_array(self) -> np.ndarray:
        return np.array([self.x_m, self.y_m, self.phi_rad, self.vx_m_s, self.vy_m_s,
                         self.omega_rad_s])

    @classmethod
    def from_array(cls, values: np.ndarray) -> RobotState:
        return cls(*np.asarray(values, dtype=np.float64).tolist())

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self.vx_m_s, self.vy_m_s)
