"""How numbers travel in the graph's messages, in one place for the nodes and the in-process
runner (which must reproduce the graph to the last bit).

Stamps are whole nanoseconds (builtin_interfaces/Time), headings are quaternions about Z, and
Odometry twists are in the robot frame (REP-103/105).
"""

from __future__ import annotations

import math
from typing import Any


def split_stamp(seconds: float) -> tuple[int, int]:
    """(sec, nanosec) of a time in seconds, rounded to the nanosecond."""
    total = round(seconds * 1e9)
    return total // 1_000_000_000, total % 1_000_000_000


def join_stamp(sec: int, nanosec: int) -> float:
    return sec + nanosec * 1e-9


def stamp_ns(stamp: Any) -> int:
    """A builtin_interfaces/Time as whole nanoseconds: exact, for comparing stamps."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def through_stamp(seconds: float) -> float:
    """A time as a subscriber reads it back from a message stamp."""
    return join_stamp(*split_stamp(seconds))


def yaw_to_quaternion(phi_rad: float) -> tuple[float, float]:
    """(z, w) of the rotation by ``phi_rad`` about Z (x = y = 0)."""
    return math.sin(phi_rad / 2.0), math.cos(phi_rad / 2.0)


def quaternion_to_yaw(z: float, w: float) -> float:
    return 2.0 * math.atan2(z, w)


def body_twist(phi_rad: float, vx_m_s: float, vy_m_s: float) -> tuple[float, float]:
    """The platform-frame velocity (vx, vy) expressed in the robot frame."""
    cos_phi, sin_phi = math.cos(phi_rad), math.sin(phi_rad)
    return cos_phi * vx_m_s + sin_phi * vy_m_s, -sin_phi * vx_m_s + cos_phi * vy_m_s


# The line a node prints at shutdown with what it published (node_runtime.PublicationCounter).
PUBLISHED_MARKER = 'published message counts: '

# The nodes of the graph, by name (a params file's sections name them).
GRAPH_NODE_NAMES = ('dynamics_node', 'vision_node', 'controller_node')

# The inherited fd of the orchestrator's lifeline pipe (node_runtime): end-of-file = it died.
LIFELINE_ENV = 'OMNI_MICRO_LIFELINE_FD'
