"""A stand-in for the real robot's driver, written from ros2_control's conventions, not from
omni-micro's nodes.

What a robot driver does: it reads a trajectory_msgs/JointTrajectory (joint_trajectory_controller:
``header.stamp`` the start, 0 for now; ``time_from_start`` per point) and publishes
sensor_msgs/JointState for its joints at its control rate (joint_state_broadcaster: 50 Hz,
reliable, depth 10, stamped with the system clock's now). Its joints are the ones omni-micro
documents: ``steering_joint`` and ``wheel_1_joint`` .. ``wheel_3_joint``.

Its topics are relative, as a ros2_control driver's: in its namespace (``__ns:=/robot_1``, as a
lab starts one driver per robot) they are ``/robot_1/joint_states`` and so on.

Its "hardware" is the slip core run on the wall clock at real time (omni_micro_sim's plain
modules: the physics stands for the robot, not for its driver). It also publishes the pose it
really has on ``bench_truth/odom``, which a real robot cannot: the stand-in camera renders it.

    python robot_driver.py [x_m y_m phi_rad [FIRST_STATE_AFTER_S [NAMESPACE]]]
    (FIRST_STATE_AFTER_S: its hardware comes up that long after the node, which publishes
    nothing until then, as a driver waiting for its controller board does)
"""

import math
import sys
import time

import rclpy
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory

from omni_micro_sim import paper
from omni_micro_sim.state import RobotState
from omni_micro_sim.stepper import GridSimulator
from omni_micro_sim.wheel_trajectory import TrajectoryPoint, command_from_points

JOINTS = ('steering_joint', 'wheel_1_joint', 'wheel_2_joint', 'wheel_3_joint')
CONTROL_RATE_HZ = 50.0


class StandInRobot(Node):
    def __init__(self, pose: tuple[float, float, float], first_state_after_s: float = 0.0) -> None:
        super().__init__('standin_robot_driver')
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        self.states = self.create_publisher(JointState, 'joint_states', qos)
        self.truth = self.create_publisher(Odometry, 'bench_truth/odom', qos)
        self.create_subscription(JointTrajectory, 'wheel_trajectory', self.on_trajectory, qos)
        self.robot = GridSimulator(paper.FIG11_OPEN_LOOP.robot(),
                                   period_s=1.0 / CONTROL_RATE_HZ,
                                   state=RobotState(*pose))
        self.robot.load_kernels()
        # The hardware's time 0 is the system clock when it comes up; its loop runs on the wall
        # clock.
        self.origin_ns = time.time_ns() + round(first_state_after_s * 1e9)
        self.create_timer(1.0 / CONTROL_RATE_HZ, self.on_control_tick)

    def hardware_time_s(self, sec: int, nanosec: int) -> float:
        return (sec * 1_000_000_000 + nanosec - self.origin_ns) * 1e-9

    def on_trajectory(self, msg: JointTrajectory) -> None:
        stamp = msg.header.stamp
        start = (self.robot.time_s if stamp.sec == 0 and stamp.nanosec == 0
                 else self.hardware_time_s(stamp.sec, stamp.nanosec))
        points = [TrajectoryPoint(p.time_from_start.sec + p.time_from_start.nanosec * 1e-9,
                                  list(p.positions), list(p.velocities)) for p in msg.points]
        try:
            self.robot.schedule(command_from_points(list(msg.joint_names), points, start,
                                                   self.robot.time_s, self.robot.limits))
        except ValueError as error:
            self.get_logger().error(f'trajectory refused: {error}')

    def on_control_tick(self) -> None:
        now_s = (time.time_ns() - self.origin_ns) * 1e-9
        if now_s < 0.0:
            # The hardware is not up: the driver says nothing, the robot stands where it is.
            self.publish_truth(self.robot.sample().state, time.time_ns())
            return
        while self.robot.time_s + self.robot.period_s <= now_s:
            self.publish(self.robot.advance())

    def publish(self, sample) -> None:
        total = self.origin_ns + round(sample.time_s * 1e9)
        state = JointState()
        state.header.stamp.sec, state.header.stamp.nanosec = divmod(total, 1_000_000_000)
        state.name = list(JOINTS)
        state.position = [float(sample.steering_rad),
                          *(float(v) for v in sample.wheel_rotations_rad)]
        state.velocity = [float(sample.steering_rate_rad_s),
                          *(float(v) for v in sample.wheel_speeds_rad_s)]
        self.states.publish(state)
        self.publish_truth(sample.state, total)

    def publish_truth(self, robot: RobotState, stamp_ns: int) -> None:
        """Where the robot really is (what the stand-in camera renders)."""
        truth = Odometry()
        truth.header.stamp.sec, truth.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
        truth.header.frame_id = 'platform'
        truth.pose.pose.position.x, truth.pose.pose.position.y = robot.x_m, robot.y_m
        truth.pose.pose.orientation.z = float(math.sin(robot.phi_rad / 2))
        truth.pose.pose.orientation.w = float(math.cos(robot.phi_rad / 2))
        truth.twist.twist.linear.x, truth.twist.twist.linear.y = robot.vx_m_s, robot.vy_m_s
        truth.twist.twist.angular.z = robot.omega_rad_s
        self.truth.publish(truth)


def main() -> None:
    x, y, phi = (float(v) for v in sys.argv[1:4]) if len(sys.argv) >= 4 else (0.0, 0.0, 0.0)
    first_state_after_s = float(sys.argv[4]) if len(sys.argv) >= 5 else 0.0
    namespace = sys.argv[5] if len(sys.argv) >= 6 else '/'
    rclpy.init(args=['--ros-args', '-r', f'__ns:={namespace}'])
    node = StandInRobot((x, y, phi), first_state_after_s)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
