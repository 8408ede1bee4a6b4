"""How numbers travel in the graph's messages, in one place for the nodes and the in-process
runner (which must reproduce the graph to the last bit).

Stamps are whole nanoseconds (builtin_interfaces/Time), headings are quaternions about Z, and
Odometry twists are in the robot frame (REP-103/105).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

# The joints of /joint_states and /wheel_trajectory (omni_micro_sim.wheel_trajectory says how a
# command uses them): the common steering of the three wheels, and each wheel's spin.
STEERING_JOINT = 'steering_joint'
WHEEL_JOINTS = ('wheel_1_joint', 'wheel_2_joint', 'wheel_3_joint')
JOINT_NAMES = (STEERING_JOINT, *WHEEL_JOINTS)
# The robot's frames (REP-105), prefixed by its namespace in a fleet (robot_1/odom).
ODOM_FRAME = 'odom'
BASE_FRAME = 'base_link'
# The platform's own frame, every robot's: where goals and captures are (each node's frame_id).
PLATFORM_FRAME = 'platform'


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


# The radius holding 95 % of a 2-D Gaussian's draws, in standard deviations: sqrt(-2 ln 0.05).
RADIUS_95_PER_SIGMA = math.sqrt(-2.0 * math.log(0.05))


@dataclass(frozen=True)
class CaptureUncertainty:
    """One capture's standard deviations: x and y of the position, and the heading.

    A camera publishes them beside each PoseStamped capture as a PoseWithCovarianceStamped
    (docs/graph.md, "The camera contract"); the covariance layout is :meth:`covariance`.
    """

    x_sigma_m: float
    y_sigma_m: float
    heading_sigma_rad: float

    @property
    def radius_95_m(self) -> float:
        """Radius around the capture that holds the true position with 95 % probability
        (exact for equal x and y spreads; the larger one is used otherwise)."""
        return RADIUS_95_PER_SIGMA * max(self.x_sigma_m, self.y_sigma_m)

    def averaged(self, count: int) -> CaptureUncertainty:
        """The spread of the mean of ``count`` captures with independent errors."""
        root = math.sqrt(count)
        return CaptureUncertainty(self.x_sigma_m / root, self.y_sigma_m / root,
                                  self.heading_sigma_rad / root)

    def covariance(self) -> list[float]:
        """Row-major 6 x 6 covariance of (x, y, z, roll, pitch, yaw), as in
        geometry_msgs/PoseWithCovariance. The platform fixes z, roll and pitch: variance 0."""
        matrix = [0.0] * 36
        matrix[0] = self.x_sigma_m ** 2
        matrix[7] = self.y_sigma_m ** 2
        matrix[35] = self.heading_sigma_rad ** 2
        return matrix

    @classmethod
    def from_covariance(cls, matrix: list[float] | tuple[float, ...]) -> CaptureUncertainty:
        """Read back :meth:`covariance` (or a real tracker's own estimate).

        Raises
        ------
        ValueError
            If the matrix is not 36 values or a needed variance is negative or not finite.
        """
        values = list(matrix)
        if len(values) != 36:
            raise ValueError(f'a pose covariance has 36 values, got {len(values)}')
        sigmas = []
        for name, index in (('x', 0), ('y', 7), ('yaw', 35)):
            variance = float(values[index])
            if not math.isfinite(variance) or variance < 0.0:
                raise ValueError(
                    f'the {name} variance of a capture must be finite and >= 0, got {variance!r}')
            sigmas.append(math.sqrt(variance))
        return cls(*sigmas)


# The platform goals lie on, in its own frame (m): what the macro camera sees, centred 50 mm
# along x so that the paper's moves, (0,0)->(100,0) mm and (0,0)->(10.15,10.15) mm, both lie on
# it. controller_node refuses a goal off it; the cameras' defaults are built on it.
PLATFORM_CENTER_M = (0.05, 0.0)
PLATFORM_SIZE_M = (0.15, 0.15)
# The micro work platform the micro camera watches (m), centred on the goal of Fig. 11.
MICRO_FIELD_CENTER_M = (0.1, 0.0)
MICRO_FIELD_SIZE_M = (0.002, 0.002)
# A goal is reached within this distance (m): the end rule the paper leaves open. The
# controller's tolerance_m by default, and the circle a viewer draws around the goal.
GOAL_TOLERANCE_M = 3.0e-6

# The key of the simulated time (s, repr of a float) every /controller/status and /camera/status
# carries: the time of the decision or observation it says (a capture, a timeout on the robot's
# clock, a goal's arrival), not of its publication. A recorder writes the status at that time,
# so that the same run records the same bag. (An outcome's sim_time_s is another number: the
# run's time as reported, its last capture's.)
STATUS_TIME_KEY = 'status_time_s'
# The key a /controller/status that ends a goal carries (its value: the outcome's name).
OUTCOME_KEY = 'outcome'
# What a /camera/<name>/tracker_status says of a driver's frames (stamped on the wall clock) once
# measured: how old they are on arrival and its captures in motion when published (s, the
# largest of the latest frames), their rate by their stamps (Hz), and the topic they come on.
FRAME_AGE_KEY = 'frame_age_s'
CAPTURE_AGE_KEY = 'capture_age_s'
FRAME_RATE_KEY = 'frame_rate_hz'
IMAGE_TOPIC_KEY = 'image_topic'
# A tracker's frames lost on the way (omni_micro_vision.frame_losses): the latest stretch's
# count of the frames the driver sent, since when (the driver's clock), the likely cause; and all
# lost of all sent since the tracker started.
FRAMES_LOST_KEY = 'frames_lost'
FRAMES_SENT_KEY = 'frames_sent'
FRAMES_LOST_SINCE_KEY = 'frames_lost_since_s'
FRAMES_LOST_CAUSE_KEY = 'frames_lost_cause'
FRAMES_LOST_TOTAL_KEY = 'frames_lost_total'
FRAMES_SENT_TOTAL_KEY = 'frames_sent_total'

# The line a node prints at shutdown with what it published (node_runtime.PublicationCounter).
PUBLISHED_MARKER = 'published message counts: '

# The inherited fd of the orchestrator's lifeline pipe (node_runtime): end-of-file = it died.
LIFELINE_ENV = 'OMNI_MICRO_LIFELINE_FD'
# A seed reaches the nodes as a ROS integer parameter (int64): the largest one a run can take.
MAX_SEED = 2**63 - 1
