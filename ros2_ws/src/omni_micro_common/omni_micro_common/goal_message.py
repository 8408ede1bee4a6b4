"""The ``/goal_pose`` message a controller reads: a point on the platform, stamped with the
simulated time the goal counts from. Beside the contracts, for whoever hands a controller its
goal (the orchestration, for one robot or each robot of a fleet)."""

from __future__ import annotations

from geometry_msgs.msg import PoseStamped

from omni_micro_common.conventions import PLATFORM_FRAME, split_stamp


def goal_pose(goal_m: tuple[float, float], stamp_s: float) -> PoseStamped:
    """A goal as every controller reads it: on the platform, stamped ``stamp_s``."""
    goal = PoseStamped()
    goal.header.stamp.sec, goal.header.stamp.nanosec = split_stamp(stamp_s)
    goal.header.frame_id = PLATFORM_FRAME
    goal.pose.position.x, goal.pose.position.y = float(goal_m[0]), float(goal_m[1])
    goal.pose.orientation.w = 1.0
    return goal
