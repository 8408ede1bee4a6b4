"""ROS 2 adapter of the scene: visualization_msgs/MarkerArray on /markers, for RViz 2 and Foxglove.

Only listens (/odom, /wheel_slip, /wheel_trajectory, /goal_pose and the cameras'
captures) and publishes /markers in the ``platform`` frame, stamped with the simulated time of the
odometry it draws. It takes no part in the lockstep, so the graph runs the same with or without
it. What is drawn is :class:`omni_micro_vision.scene.Scene`'s; this node only moves numbers.

Every ``publish_every_ticks`` odometry samples it publishes the robot, its slip and the growing
end of the route; after an event (a goal, a capture, a move) the event's markers too; and every
``refresh_every_ticks`` samples everything, so that a viewer that connects late sees the whole run.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import Marker, MarkerArray

from omni_micro_sim.conventions import CaptureUncertainty, quaternion_to_yaw
from omni_micro_sim.node_runtime import run_node
from omni_micro_sim.qos import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_QOS,
    CAPTURE_TOPICS,
    DATA_QOS,
    PER_TICK_SUBSCRIPTION_EVENTS,
)
from omni_micro_sim.wheel_trajectory import STEERING_JOINT
from omni_micro_vision.camera import DEFAULT_RIG, CameraConfigError, CameraModel, CameraRig
from omni_micro_vision.scene import RobotGeometry, Scene, Shape, move_of, slip_of

MARKER_TYPES = {'arrow': Marker.ARROW, 'disc': Marker.CYLINDER,
                'sphere_list': Marker.SPHERE_LIST, 'line_strip': Marker.LINE_STRIP,
                'line_list': Marker.LINE_LIST, 'text': Marker.TEXT_VIEW_FACING}


def to_marker(shape: Shape, frame_id: str, stamp: Time, marker: Marker | None = None) -> Marker:
    """The Marker of ``shape``; ``marker``, a previous one of the same shape, is updated in place
    (building rclpy messages is most of this node's time)."""
    if marker is None:
        marker = Marker(ns=shape.namespace, id=shape.id, type=MARKER_TYPES[shape.kind],
                        action=Marker.ADD, frame_locked=False)
        marker.header.frame_id = frame_id
        marker.pose.orientation.w = 1.0
    marker.header.stamp = stamp
    colour = marker.color
    colour.r, colour.g, colour.b, colour.a = shape.colour
    if shape.kind in ('disc', 'text'):
        marker.pose.position.x, marker.pose.position.y = shape.points[0]
        if shape.kind == 'disc':
            marker.scale.x = marker.scale.y = shape.size_m
            marker.scale.z = shape.size_m * 0.02
        else:
            marker.scale.z = shape.size_m
            marker.text = shape.text
        return marker
    points = marker.points
    if len(points) == len(shape.points):
        for point, (x, y) in zip(points, shape.points, strict=True):
            point.x, point.y = x, y
    else:
        marker.points = [Point(x=x, y=y, z=0.0) for x, y in shape.points]
    if shape.kind == 'arrow':
        # Shaft diameter, head diameter, head length (RViz's and Foxglove's convention).
        length = math.dist(*shape.points)
        marker.scale.x = shape.size_m
        marker.scale.y = 2.0 * shape.size_m
        marker.scale.z = min(4.0 * shape.size_m, 0.3 * length) if length > 0 else 0.0
    elif shape.kind == 'sphere_list':
        marker.scale.x = marker.scale.y = marker.scale.z = shape.size_m
    else:
        marker.scale.x = shape.size_m
    return marker


class MarkersNode(Node):
    def __init__(self) -> None:
        super().__init__('markers_node')
        self.frame_id = self.declare_parameter('frame_id', 'platform').value
        self.publish_every = int(self.declare_parameter('publish_every_ticks', 5).value)
        self.refresh_every = int(self.declare_parameter('refresh_every_ticks', 50).value)
        if self.publish_every < 1 or self.refresh_every < 1:
            raise CameraConfigError(
                f'publish_every_ticks and refresh_every_ticks must be >= 1, got '
                f'{self.publish_every} and {self.refresh_every}')
        cameras = {}
        for name in ('macro', 'micro'):
            default: CameraModel = getattr(DEFAULT_RIG, name)
            cameras[name] = CameraModel(
                name, self.declare_parameter(f'{name}.center_m', list(default.center_m)).value,
                self.declare_parameter(f'{name}.field_m', list(default.field_m)).value)
        nominal = RobotGeometry()
        offsets = self.declare_parameter('robot.wheel_offsets_rad',
                                         list(nominal.wheel_offsets_rad)).value
        if len(offsets) != 3 or not all(math.isfinite(v) for v in offsets):
            raise CameraConfigError(
                f'robot.wheel_offsets_rad must be three finite angles, got {list(offsets)}')
        tolerance = float(self.declare_parameter('tolerance_m', 3.0e-6).value)
        slip_arrow = float(self.declare_parameter('slip_arrow_s', 2.0).value)
        if not (tolerance > 0 and slip_arrow > 0):
            raise CameraConfigError(f'tolerance_m and slip_arrow_s must be > 0, got '
                                    f'{tolerance} and {slip_arrow}')
        self.scene = Scene(CameraRig(**cameras), RobotGeometry(
            wheel_offsets_rad=(float(offsets[0]), float(offsets[1]), float(offsets[2]))),
                           tolerance_m=tolerance, slip_arrow_s=slip_arrow)
        self.published = 0
        self.handled = 0          # messages taken in (the drain at shutdown watches it)
        self._ticks = 0
        self._changed: set[str] = set()     # event groups to send with the next array
        self._stamp = Time()
        self._markers: dict[tuple[str, int], Marker] = {}
        quiet = PER_TICK_SUBSCRIPTION_EVENTS
        self.create_subscription(Odometry, '/odom', self._on_odometry, DATA_QOS,
                                 event_callbacks=quiet)
        # Per-tick: each subscriber costs the dynamics node a delivery per tick, so the
        # steering comes from the commands (/wheel_trajectory), and the slip is kept as bytes
        # and decoded once per publication.
        self._latest: dict[str, bytes] = {}
        self._steering_at: list[tuple[int, float]] = []     # (start stamp ns, steering)
        self.create_subscription(JointState, '/wheel_slip', self._keeper('/wheel_slip'),
                                 DATA_QOS, raw=True, event_callbacks=quiet)
        self.create_subscription(JointTrajectory, '/wheel_trajectory', self._on_trajectory,
                                 DATA_QOS)
        self.create_subscription(PoseStamped, '/goal_pose', self._on_goal, 10)
        for name, topic in CAPTURE_TOPICS.items():
            self.create_subscription(PoseStamped, topic, self._capture_reader(name),
                                     CAPTURE_QOS)
        for name, topic in CAPTURE_COVARIANCE_TOPICS.items():
            self.create_subscription(PoseWithCovarianceStamped, topic,
                                     self._uncertainty_reader(name), CAPTURE_QOS)
        # Made last: once the orchestration sees it, every subscription above exists.
        self.publisher = self.create_publisher(MarkerArray, '/markers', DATA_QOS)

    # -- inputs ------------------------------------------------------------------------------
    def _on_odometry(self, msg: Odometry) -> None:
        pose = msg.pose.pose
        self.scene.on_odometry(pose.position.x, pose.position.y,
                               quaternion_to_yaw(pose.orientation.z, pose.orientation.w))
        self._stamp = msg.header.stamp
        self._ticks += 1
        self.handled += 1
        if self._ticks % self.publish_every and self._ticks % self.refresh_every:
            return
        self._read_wheels()
        if self._ticks % self.refresh_every == 0:
            self._publish(self.scene.robot_shapes() + self.scene.route_shapes(only_last=False)
                          + self.scene.static_shapes())
        else:
            shapes = self.scene.robot_shapes() + self.scene.route_shapes(only_last=True)
            if self._changed:
                shapes += self.scene.static_shapes(frozenset(self._changed), newest_only=True)
            self._publish(shapes)

    def _keeper(self, topic: str) -> Callable[[bytes], None]:
        def keep(data: bytes) -> None:
            self._latest[topic] = data
            self.handled += 1
        return keep

    def _read_wheels(self) -> None:
        now = self._stamp.sec * 10**9 + self._stamp.nanosec
        while self._steering_at and self._steering_at[0][0] <= now:
            self.scene.on_steering(self._steering_at.pop(0)[1])
        if '/wheel_slip' in self._latest:
            slip = deserialize_message(self._latest['/wheel_slip'], JointState)
            self.scene.on_slip(*slip_of(slip.name, slip.velocity))


    def _on_trajectory(self, msg: JointTrajectory) -> None:
        self.handled += 1
        if len(msg.points) < 2 or STEERING_JOINT not in msg.joint_names:
            return    # a stop: nothing to draw
        steering, length = move_of(msg.joint_names, msg.points[0].positions,
                                   msg.points[-1].positions, self.scene.robot.wheel_radius_m)
        self.scene.on_move(steering, length)
        # Steering is exact and instantaneous at the command's start (the wheel command
        # contract): the wheels are drawn turned from that stamp on.
        self._steering_at.append((msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec,
                                  steering))
        self._changed.add('moves')

    def _on_goal(self, msg: PoseStamped) -> None:
        self.handled += 1
        self.scene.on_goal(msg.pose.position.x, msg.pose.position.y)
        self._changed.add('goal')

    def _capture_reader(self, camera: str) -> Callable[[PoseStamped], None]:
        def on_capture(msg: PoseStamped) -> None:
            self.handled += 1
            self.scene.on_capture(camera, msg.pose.position.x, msg.pose.position.y)
            self._changed.add('captures')
        return on_capture

    def _uncertainty_reader(self, camera: str) -> Callable[[PoseWithCovarianceStamped], None]:
        def on_uncertainty(msg: PoseWithCovarianceStamped) -> None:
            self.handled += 1
            pose = msg.pose.pose
            uncertainty = CaptureUncertainty.from_covariance(list(msg.pose.covariance))
            self.scene.on_capture_uncertainty(camera, pose.position.x, pose.position.y,
                                              uncertainty.radius_95_m)
            self._changed.add('captures')
        return on_uncertainty

    def _publish(self, shapes: list[Shape]) -> None:
        self._changed.clear()
        markers = []
        if self.scene.cleared:
            # The last goal's captures and moves go; everything still drawn is sent again.
            self.scene.cleared = False
            self._markers.clear()
            clear = Marker(action=Marker.DELETEALL)
            clear.header.frame_id = self.frame_id
            clear.header.stamp = self._stamp
            markers.append(clear)
            shapes = (self.scene.robot_shapes() + self.scene.route_shapes(only_last=False)
                      + self.scene.static_shapes())
        for shape in shapes:
            key = (shape.namespace, shape.id)
            self._markers[key] = to_marker(shape, self.frame_id, self._stamp,
                                           self._markers.get(key))
            markers.append(self._markers[key])
        self.publisher.publish(MarkerArray(markers=markers))
        self.published += 1


def main(args: list[str] | None = None) -> None:
    # Not in the lockstep, it may lag at --rtf max: it draws what is queued before it leaves.
    run_node(MarkersNode, config_errors=(CameraConfigError,), args=args,
             drain=lambda node: node.handled)


if __name__ == '__main__':
    main()
