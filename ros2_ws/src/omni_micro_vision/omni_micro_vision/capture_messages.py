"""A capture as the camera contract publishes it (docs/graph.md, "The camera contract"): a
geometry_msgs/PoseStamped of the robot on the platform, and the same pose with its uncertainty
as a PoseWithCovarianceStamped; vision_node and tracker_node build theirs here."""

from __future__ import annotations

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped

from omni_micro_common.conventions import CaptureUncertainty, yaw_to_quaternion


def capture_pose(sec: int, nanosec: int, frame_id: str, x_m: float, y_m: float,
                 phi_rad: float) -> PoseStamped:
    """The robot at (x, y) heading ``phi_rad`` in ``frame_id``, stamped (sec, nanosec)."""
    msg = PoseStamped()
    msg.header.stamp.sec, msg.header.stamp.nanosec = sec, nanosec
    msg.header.frame_id = frame_id
    msg.pose.position.x, msg.pose.position.y = x_m, y_m
    msg.pose.orientation.z, msg.pose.orientation.w = yaw_to_quaternion(phi_rad)
    return msg


def with_uncertainty(pose: PoseStamped, uncertainty: CaptureUncertainty
                     ) -> PoseWithCovarianceStamped:
    """``pose`` again, same header, with the covariance of ``uncertainty``."""
    msg = PoseWithCovarianceStamped(header=pose.header)
    msg.pose.pose = pose.pose
    msg.pose.covariance = uncertainty.covariance()
    return msg
