"""The paper's scenarios and published numbers, defined once for the CLI, figures and tests."""

from __future__ import annotations

import math
from dataclasses import dataclass

from omni_micro_sim.parameters import MotorLimits, RobotParameters


@dataclass(frozen=True)
class OpenLoopScenario:
    """An open-loop move from rest at the origin with phi = 0."""

    name: str
    steering_deg: float
    duration_s: float
    wheel_offsets_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wheel1_active: bool = True

    def robot(self, base: RobotParameters | None = None) -> RobotParameters:
        return (base or RobotParameters()).replace(
            wheel_offsets_rad=tuple(math.radians(v) for v in self.wheel_offsets_deg),
            wheel1_active=self.wheel1_active)


def duration_for_distance(distance_m: float, limits: MotorLimits | None = None,
                          base: RobotParameters | None = None) -> float:
    """Move time t whose commanded wheel rotation (cruise speed * t) rolls ``distance_m``."""
    limits = limits or MotorLimits()
    return distance_m / ((base or RobotParameters()).wheel_radius_m * limits.cruise_speed_rad_s)


# Section 3.5.3: wheels 2 and 3 aligned 3 deg and 2 deg from wheel 1.
SECTION_353_OFFSETS_DEG = (0.0, 3.0, 2.0)
# Fig. 8: (0,0) to (28.71,0) mm in 2 s; "the stop location has a 0.4727 mm drift from the goal".
FIG8 = OpenLoopScenario('fig8', 0.0, 2.0, SECTION_353_OFFSETS_DEG)
FIG8_PUBLISHED_DRIFT_MM = 0.4727
# Fig. 11: (0,0) to (100,0) mm in 7 s; open loop "the deviation reaches 13mm".
FIG11_OPEN_LOOP = OpenLoopScenario('fig11-open-loop', 0.0, 7.0, SECTION_353_OFFSETS_DEG)
FIG11_PUBLISHED_OPEN_LOOP_DEVIATION_MM = 13.0
FIG11_PUBLISHED_CLOSED_LOOP_DEVIATION_MM = 0.0124
FIG11_GOAL_M = (0.100, 0.0)
# Fig. 6: a 14.355 mm move (t = 1 s) at every direction angle, wheel 1 active or passive.
FIG6_DISTANCE_M = 14.355e-3
# Fig. 7: (0,0) to (10.15,10.15) mm with wheels 2 and 3 offset by xi in -10..10 deg.
FIG7_GOAL_M = (10.15e-3, 10.15e-3)
FIG7_OFFSET_RANGE_DEG = (-10.0, 10.0)
