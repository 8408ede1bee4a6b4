"""A stand-in for vision_node that follows only the camera contract in the README.

It knows nothing of omni-micro's camera model: it watches /odom, waits until the robot has been
still for 50 ms, and then publishes the exact pose on /camera/macro/pose, stamped with the
exposure time, at 10 frames per second, until the robot moves again.
"""

import math

import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy


class StandInCamera(Node):
    def __init__(self):
        super().__init__('standin_camera')
        self.publisher = self.create_publisher(
            PoseStamped, '/camera/macro/pose',
            QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE))
        self.create_subscription(Odometry, '/odom', self.on_odometry,
                                 QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
        self.still_since: float | None = None
        self.next_frame = 0.0

    def on_odometry(self, msg: Odometry) -> None:
        stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        twist = msg.twist.twist
        if math.hypot(twist.linear.x, twist.linear.y) > 1e-6 or abs(twist.angular.z) > 1e-4:
            self.still_since = None
            return
        if self.still_since is None:
            self.still_since, self.next_frame = stamp, stamp + 0.05
        while self.next_frame <= stamp + 1e-9:
            capture = PoseStamped()
            capture.header.frame_id = 'platform'
            capture.header.stamp.sec = int(self.next_frame)
            capture.header.stamp.nanosec = round((self.next_frame % 1) * 1e9) % 1000000000
            capture.pose = msg.pose.pose
            self.publisher.publish(capture)
            self.next_frame += 0.1


def main():
    rclpy.init()
    node = StandInCamera()
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
