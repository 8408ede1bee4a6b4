"""The per-tick messages of dynamics_node as CDR templates (:mod:`omni_micro_common.cdr`):
the robot writes them, vision_node, controller_node and markers_node read them, without
rclpy's conversion between Python messages and C.

A reader takes a message of another layout (another publisher's frame names, joint order or
covariance) as an ordinary message: the template only reads bytes it knows.
"""

from __future__ import annotations

from dataclasses import dataclass

from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from omni_micro_common.cdr import MessageTemplate
from omni_micro_common.conventions import JOINT_NAMES

SLIP_NAMES = [f'wheel_{k}_{part}' for k in (1, 2, 3) for part in ('longitudinal', 'transverse')]
STAMP = {'header.stamp.sec': 'int32', 'header.stamp.nanosec': 'uint32'}
# The odometry's numbers, in the order a template writes and reads them.
ODOMETRY_FIELDS = {**STAMP, **dict.fromkeys((
    'pose.pose.position.x', 'pose.pose.position.y', 'pose.pose.orientation.z',
    'pose.pose.orientation.w', 'twist.twist.linear.x', 'twist.twist.linear.y',
    'twist.twist.angular.z'), 'float64')}
# The joint state's: stamp, then positions and velocities in JOINT_NAMES order.
JOINT_STATE_FIELDS = {**STAMP, **{f'{array}[{k}]': 'float64' for array in ('position', 'velocity')
                                  for k in range(len(JOINT_NAMES))}}


@dataclass(frozen=True)
class TickTemplates:
    """The four per-tick messages, in the order dynamics_node publishes them."""

    clock: MessageTemplate
    odometry: MessageTemplate
    joint_state: MessageTemplate
    slip: MessageTemplate


def odometry_template(odom_frame: str = 'odom', base_frame: str = 'base_link') -> MessageTemplate:
    odometry = Odometry()
    odometry.header.frame_id = odom_frame
    odometry.child_frame_id = base_frame
    return MessageTemplate(odometry, ODOMETRY_FIELDS)


def joint_state_template(base_frame: str = 'base_link') -> MessageTemplate:
    joints = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                        velocity=[0.0] * len(JOINT_NAMES))
    joints.header.frame_id = base_frame
    return MessageTemplate(joints, JOINT_STATE_FIELDS)


def tick_templates(odom_frame: str, base_frame: str) -> TickTemplates:
    slip = JointState(name=SLIP_NAMES, velocity=[0.0] * len(SLIP_NAMES))
    slip.header.frame_id = base_frame
    return TickTemplates(
        MessageTemplate(Clock(), {'clock.sec': 'int32', 'clock.nanosec': 'uint32'}),
        odometry_template(odom_frame, base_frame),
        joint_state_template(base_frame),
        MessageTemplate(slip, {**STAMP, **{f'velocity[{k}]': 'float64'
                                           for k in range(len(SLIP_NAMES))}}))
