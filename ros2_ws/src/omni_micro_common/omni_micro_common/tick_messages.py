"""The per-tick messages of dynamics_node as CDR templates (:mod:`omni_micro_common.cdr`):
the robot writes them, vision_node, controller_node and markers_node read them, without
rclpy's conversion between Python messages and C.

A reader takes a message of another layout (another publisher's frame names, joint order or
covariance) as an ordinary message: the template only reads bytes it knows.
"""

from __future__ import annotations

from dataclasses import dataclass

from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from omni_micro_common.cdr import MessageTemplate
from omni_micro_common.conventions import (
    BASE_FRAME,
    JOINT_NAMES,
    ODOM_FRAME,
    STEERING_JOINT,
    WHEEL_JOINTS,
)
from omni_micro_common.topic_names import namespaced_frame

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


def odometry_template(odom_frame: str = ODOM_FRAME,
                      base_frame: str = BASE_FRAME) -> MessageTemplate:
    odometry = Odometry()
    odometry.header.frame_id = odom_frame
    odometry.child_frame_id = base_frame
    return MessageTemplate(odometry, ODOMETRY_FIELDS)


def joint_state_template(base_frame: str = BASE_FRAME) -> MessageTemplate:
    joints = JointState(name=list(JOINT_NAMES), position=[0.0] * len(JOINT_NAMES),
                        velocity=[0.0] * len(JOINT_NAMES))
    joints.header.frame_id = base_frame
    return MessageTemplate(joints, JOINT_STATE_FIELDS)


def robot_odometry_template(namespace: str) -> MessageTemplate:
    """The odometry of the robot in ``namespace`` on the default frames (``robot_1/odom``):
    a reader built for another robot's frames still reads it, deserialized in full, slower."""
    return odometry_template(namespaced_frame(namespace, ODOM_FRAME),
                             namespaced_frame(namespace, BASE_FRAME))


def robot_joint_state_template(namespace: str) -> MessageTemplate:
    """The joint states of the robot in ``namespace`` (frame ``robot_1/base_link``)."""
    return joint_state_template(namespaced_frame(namespace, BASE_FRAME))


@dataclass(frozen=True)
class WheelState:
    """What a controller reads of a JointState: the wheels' rotations and speeds in
    WHEEL_JOINTS order, the steering's rate (0 when not said), the stamp."""

    sec: int
    nanosec: int
    rotations_rad: tuple[float, ...]
    speeds_rad_s: tuple[float, ...]
    steering_rate_rad_s: float

    @property
    def turning(self) -> bool:
        """A wheel or the steering moving."""
        return any(speed != 0.0 for speed in self.speeds_rad_s) or self.steering_rate_rad_s != 0.0


def read_wheel_state(template: MessageTemplate, data: bytes) -> WheelState | None:
    """A serialized JointState read in place when it has the robot's own layout (JOINT_NAMES
    order), else converted; None when it does not name every wheel."""
    values = template.read(data)
    if values is not None:
        count = len(JOINT_NAMES)
        return WheelState(int(values[0]), int(values[1]),
                          tuple(float(v) for v in values[3:2 + count]),
                          tuple(float(v) for v in values[3 + count:]), float(values[2 + count]))
    msg = deserialize_message(data, JointState)
    try:
        index = [msg.name.index(name) for name in WHEEL_JOINTS]
    except ValueError:
        return None
    steering_rate = (msg.velocity[msg.name.index(STEERING_JOINT)]
                     if STEERING_JOINT in msg.name and len(msg.velocity) == len(msg.name)
                     else 0.0)
    return WheelState(msg.header.stamp.sec, msg.header.stamp.nanosec,
                      tuple(msg.position[i] for i in index),
                      tuple(msg.velocity[i] for i in index), steering_rate)


def tick_templates(odom_frame: str, base_frame: str) -> TickTemplates:
    slip = JointState(name=SLIP_NAMES, velocity=[0.0] * len(SLIP_NAMES))
    slip.header.frame_id = base_frame
    return TickTemplates(
        MessageTemplate(Clock(), {'clock.sec': 'int32', 'clock.nanosec': 'uint32'}),
        odometry_template(odom_frame, base_frame),
        joint_state_template(base_frame),
        MessageTemplate(slip, {**STAMP, **{f'velocity[{k}]': 'float64'
                                           for k in range(len(SLIP_NAMES))}}))
