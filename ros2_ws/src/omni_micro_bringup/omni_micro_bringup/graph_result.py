"""What a run through the graph returns, one robot's or several's: the outcome, the times, where
the logs are; a single robot's final pose against its goal; each robot's log of a fleet."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from omni_micro_control.fleet_plan import Leg


@dataclass
class RobotLog:
    """One robot's part of a fleet's run, as the orchestration saw it."""

    tasks_done_s: list[float] = field(default_factory=list)
    moves: int = 0
    outcome: str = ''
    route: list[tuple[float, float, float, float]] = field(default_factory=list)  # t, x, y, phi
    legs: list[tuple[float, float, Leg]] = field(default_factory=list)   # started, ended, leg
    learnt_offsets_rad: tuple[float, float] | None = None   # its controller's last said
    # Each goal handed to its controller (stamp_s, x_m, y_m, on the robots' time), and how each
    # that ended did (at_s, outcome): as the fleet twin's RobotRun has them.
    goal_poses: list[tuple[float, float, float]] = field(default_factory=list)
    goal_pose_ends: list[tuple[float, str]] = field(default_factory=list)


@dataclass
class GraphResult:
    """A run through the graph. A single robot's (``robots`` empty) says its final pose, true
    (simulated) or as the camera last saw it (the bench), against its last goal; a fleet's says
    each robot's in ``robots`` and how close two came (its final pose fields stay NaN: no one
    pose is the run's)."""

    outcome: str     # a single robot's controller's; a fleet's: done, lost, contact or timeout
    reason: str
    sim_time_s: float
    wall_time_s: float
    log_dir: Path
    domain_id: int
    periods: int = 0
    final_x_m: float = math.nan
    final_y_m: float = math.nan
    final_phi_rad: float = math.nan
    goal_m: tuple[float, float] | None = None
    status: dict[str, str] = field(default_factory=dict)
    route: list[tuple[float, float, float]] = field(default_factory=list)       # t, x, y
    captures: list[tuple[float, float, float, str]] = field(default_factory=list)  # t, x, y, cam
    goals: list[dict[str, str]] = field(default_factory=list)   # final status of every goal
    published: dict[str, int] = field(default_factory=dict)     # per topic, all nodes
    memory_kb: dict[str, list[int]] = field(default_factory=dict)  # RSS after each goal
    respawns: dict[str, int] = field(default_factory=dict)
    robots: list[RobotLog] = field(default_factory=list)
    # Of the centres, on the robots' 10 Hz odometry (a contact is dynamics_node's, every tick).
    closest_gap_m: float = math.inf
    closest_pair: tuple[int, int] | None = None

    @property
    def deviation_m(self) -> float:
        if self.goal_m is None:
            return math.nan
        return math.hypot(self.final_x_m - self.goal_m[0], self.final_y_m - self.goal_m[1])

    def as_json(self) -> dict[str, object]:
        """A single robot's run (a fleet's has no one goal), as ``run --json`` prints it."""
        assert self.goal_m is not None, 'as_json tells a single robot\'s run'
        goal = self.goal_m
        return {
            'outcome': self.outcome, 'reason': self.reason, 'periods': self.periods,
            'final_x_mm': self.final_x_m * 1e3, 'final_y_mm': self.final_y_m * 1e3,
            'final_phi_deg': math.degrees(self.final_phi_rad),
            'deviation_mm': self.deviation_m * 1e3,
            'goal_x_mm': goal[0] * 1e3, 'goal_y_mm': goal[1] * 1e3,
            'sim_time_s': self.sim_time_s, 'wall_time_s': self.wall_time_s,
            'real_time_factor': (self.sim_time_s / self.wall_time_s
                                 if self.wall_time_s > 0 else None),
            'log_dir': str(self.log_dir), 'domain_id': self.domain_id,
        }
