"""ROS 2 adapter of the scene: visualization_msgs/MarkerArray on /markers, for RViz 2 and Foxglove.

Listens (/odom_throttle, /joint_states_throttle, /wheel_slip, /wheel_trajectory, /goal_pose and
the cameras' captures) and publishes /markers in the ``platform`` frame, stamped with the
simulated time of the odometry it draws. What is drawn is
:class:`omni_micro_vision.scene.Scene`'s; this node only moves numbers.

What an array holds depends on the stamps of what it draws, never on which message arrived
first: every input is applied in stamp order (ties: goal, move, macro capture, micro capture),
and an array is drawn only once the odometry has gone two arrays past it and each wheel stream
with a publisher (/wheel_slip, /joint_states_throttle) has reached its time. In a lockstep graph
the node is a *watcher* (:mod:`omni_micro_common.lockstep`): it reports each capture and command
it has handled on /lockstep, and time does not go more than a period past a capture, nor on at
all past a command, that it has not handled; so every event of an array is in before the
odometry that draws it (measured cost: docs/time.md). Started alone, nobody waits for it.

The robot's pose and wheels come from the throttled streams dynamics_node publishes for who only
watches (10 Hz of simulated time): at ``--rtf max`` the loop fills both cores, and each message
delivered to a process that only watches takes its share of them. A robot that publishes only
/odom and /joint_states is drawn by remapping ``/odom_throttle:=/odom
/joint_states_throttle:=/joint_states`` (or through topic_tools throttle): what is published
depends on the stamps, not on how many samples arrive.

Each ``publish_period_s`` of simulated time it publishes the robot, its slip and the growing end
of the route; after an event (a goal, a capture, a move) the event's markers too; and each
``refresh_period_s`` everything, so that a viewer that connects late sees the whole run.
"""

from __future__ import annotations

import heapq
import math
from collections import deque
from collections.abc import Callable
from typing import Any

from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from rclpy.subscription import Subscription
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory
from visualization_msgs.msg import MarkerArray

from omni_micro_common.cdr import header_stamp_ns
from omni_micro_common.conventions import (
    GOAL_TOLERANCE_M,
    PLATFORM_FRAME,
    STEERING_JOINT,
    CaptureUncertainty,
    quaternion_to_yaw,
    stamp_ns,
)
from omni_micro_common.lockstep import NOTHING_HANDLED_NS, Ack
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.qos import CAPTURE_QOS, DATA_QOS, PER_TICK_SUBSCRIPTION_EVENTS
from omni_micro_common.reader_matching import node_list_parameter, when_readers_matched
from omni_micro_common.tick_messages import robot_odometry_template
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_TOPICS,
    CAPTURE_UNCERTAINTY_SOURCES,
    GOAL_TOPIC,
    JOINT_STATES_THROTTLE_TOPIC,
    MARKERS_TOPIC,
    ODOM_THROTTLE_TOPIC,
    WHEEL_SLIP_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
)
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel, CameraRig, checked_yaw
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.marker_messages import MarkerArrayEncoder
from omni_micro_vision.scene import ROBOT, RobotGeometry, Scene, Shape, move_of, slip_of

# An array is drawn once the odometry has gone this many arrays further: in the lockstep every
# event stamped up to it (a capture, a move) has then been handled (the gate holds time a period
# past an unhandled capture, and still while a command is unhandled).
DRAW_LAG_ARRAYS = 2
# The wheel streams (/wheel_slip, /joint_states_throttle) come from writers of their own, and a
# sample the reliable protocol resends arrives after later odometry: an array waits until each
# stream that has a publisher has passed its time, but no more than this many arrays more (a
# publisher that went quiet must not stop the drawing for good).
MAX_HELD_ARRAYS = 50
# Ties between events of one stamp, applied in this order whatever order they arrived in.
EVENT_ORDER = {'goal': 0, 'move': 1, 'macro': 2, 'micro': 3}


def _period_ns(name: str, value: object) -> int:
    seconds = float(value) if isinstance(value, (int, float)) and \
        not isinstance(value, bool) else math.nan
    if not (math.isfinite(seconds) and seconds >= 1e-6):
        raise CameraConfigError(f'{name} must be a number of simulated seconds >= 1e-6, got '
                                f'{value!r}')
    return round(seconds * 1e9)


class MarkersNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options (context, parameter_overrides, ...) as rclpy's Node takes them: tests
        # build the node in-process with them.
        super().__init__('markers_node', **node_options)
        self.frame_id = self.declare_parameter('frame_id', PLATFORM_FRAME).value
        publish_s = self.declare_parameter('publish_period_s', 0.1).value
        refresh_s = self.declare_parameter('refresh_period_s', 5.0).value
        self.publish_ns, self.refresh_ns = (_period_ns(name, value) for name, value in (
            ('publish_period_s', publish_s), ('refresh_period_s', refresh_s)))
        if self.refresh_ns % self.publish_ns:
            raise CameraConfigError(f'refresh_period_s must be a whole multiple of '
                                    f'publish_period_s, got {refresh_s!r} and {publish_s!r}')
        cameras = {}
        yaws = {}
        for name in ('macro', 'micro'):
            default: CameraModel = getattr(DEFAULT_RIG, name)
            cameras[name] = CameraModel(
                name, self.declare_parameter(f'{name}.center_m', list(default.center_m)).value,
                self.declare_parameter(f'{name}.field_m', list(default.field_m)).value)
            yaws[name] = checked_yaw(f'{name}.yaw_rad',
                                     self.declare_parameter(f'{name}.yaw_rad', 0.0).value)
        nominal = RobotGeometry()
        offsets = self.declare_parameter('robot.wheel_offsets_rad',
                                         list(nominal.wheel_offsets_rad)).value
        if len(offsets) != 3 or not all(math.isfinite(v) for v in offsets):
            raise CameraConfigError(
                f'robot.wheel_offsets_rad must be three finite angles, got {list(offsets)}')
        colour = self.declare_parameter('robot.colour', list(ROBOT)).value
        if len(colour) != 4 or not all(0.0 <= v <= 1.0 for v in colour):
            raise CameraConfigError(f'robot.colour must be four numbers in [0, 1] (red, green, '
                                    f'blue, alpha), got {list(colour)}')
        label = str(self.declare_parameter('robot.label', '').value)
        tolerance = float(self.declare_parameter('tolerance_m', GOAL_TOLERANCE_M).value)
        slip_arrow = float(self.declare_parameter('slip_arrow_s', 2.0).value)
        if not (tolerance > 0 and slip_arrow > 0):
            raise CameraConfigError(f'tolerance_m and slip_arrow_s must be > 0, got '
                                    f'{tolerance} and {slip_arrow}')
        self.scene = Scene(CameraRig(**cameras), RobotGeometry(
            wheel_offsets_rad=(float(offsets[0]), float(offsets[1]), float(offsets[2]))),
                           tolerance_m=tolerance, slip_arrow_s=slip_arrow, camera_yaw_rad=yaws,
                           robot_colour=(float(colour[0]), float(colour[1]), float(colour[2]),
                                         float(colour[3])), label=label)
        self.handled = 0          # messages taken in (the drain at shutdown watches it)
        self._changed: set[str] = set()     # event groups to send with the next array
        self._stamp = Time()
        self._encoder = MarkerArrayEncoder(self.frame_id)
        # Everything is applied in stamp order, two arrays behind the odometry, so that
        # what an array holds does not depend on which message happened to arrive first (the
        # lockstep has every input of a tick published before the next tick's odometry).
        self._poses: list[tuple[int, Time, tuple[float, float, float]]] = []
        self._events: list[tuple[int, int, int, Callable[[], None]]] = []   # a heap
        self._slips: dict[int, bytes] = {}
        self._joint_states: dict[int, bytes] = {}
        # The wheel streams' readers, and the newest stamp each has delivered, by topic.
        self._wheel_streams: dict[str, Subscription] = {}
        self._newest_wheel_ns: dict[str, int] = {}
        self._held_too_long = False
        # The arrays due, oldest first: the stamp each draws, and whether it draws everything.
        self._due: deque[tuple[int, bool]] = deque()
        self._last_periods: tuple[int, int] | None = None   # (publish, refresh) of the last due
        self._sequence = 0
        # What it reports as a watcher: the latest capture and command stamps it has handled.
        self.lockstep = LockstepReporter(self)
        self._capture_handled_ns = NOTHING_HANDLED_NS
        self._command_handled_ns = NOTHING_HANDLED_NS
        # Reported at once (nothing handled yet): until the gate has a report it holds time at
        # the lead, where no throttled sample comes to make another; the reporter says it again
        # while nothing new comes (a report sent before the dynamics' reader matched is lost).
        self._report()
        self._odometry = robot_odometry_template(self.get_namespace().strip('/'))
        self._capture_source = self.declare_parameter('capture_uncertainty', 'covariance').value
        if self._capture_source not in CAPTURE_UNCERTAINTY_SOURCES:
            raise CameraConfigError(f'capture_uncertainty must be one of '
                                    f'{list(CAPTURE_UNCERTAINTY_SOURCES)}, got '
                                    f'{self._capture_source!r}')
        self.publisher = self.create_publisher(MarkerArray, MARKERS_TOPIC, DATA_QOS)
        # It listens once its writer has matched the readers that must have every array (the
        # recorder's, named by the orchestration in ``markers_readers``): the robot's clock,
        # which waits for this node's readers, then starts no sooner. The recorder matching
        # this writer is not enough: discovery runs each way at its own pace (a bag recorded
        # beside two busy processes lacked the first 3.4 s of arrays).
        readers = node_list_parameter(self, 'markers_readers')
        when_readers_matched(self, [(self.publisher, readers)], self._listen)

    def _listen(self) -> None:
        """Every subscription, /goal_pose last: once the orchestration sees that reader, every
        other one exists."""
        quiet = PER_TICK_SUBSCRIPTION_EVENTS
        self.create_subscription(Odometry, ODOM_THROTTLE_TOPIC, self._on_odometry, DATA_QOS,
                                 raw=True, event_callbacks=quiet)
        # The streams are kept as bytes and decoded once per publication. The wheels are
        # drawn at their actual steering angle (/joint_states): with a steering motion it
        # lags the commanded one.
        for topic, on_sample in ((WHEEL_SLIP_TOPIC, self._on_slip),
                                 (JOINT_STATES_THROTTLE_TOPIC, self._on_joint_state)):
            self._wheel_streams[topic] = self.create_subscription(
                JointState, topic, on_sample, DATA_QOS, raw=True, event_callbacks=quiet)
        self.create_subscription(JointTrajectory, WHEEL_TRAJECTORY_TOPIC, self._on_trajectory,
                                 DATA_QOS)
        # Each capture from one topic, as the controller reads it (the same parameter): the
        # covariance topic has the pose too, and a second subscription would double the
        # deliveries of every capture to a process that only watches.
        for name in CAPTURE_TOPICS:
            if self._capture_source == 'covariance':
                self.create_subscription(PoseWithCovarianceStamped,
                                         CAPTURE_COVARIANCE_TOPICS[name],
                                         self._capture_with_uncertainty_reader(name),
                                         CAPTURE_QOS)
            else:
                self.create_subscription(PoseStamped, CAPTURE_TOPICS[name],
                                         self._capture_reader(name), CAPTURE_QOS)
        self.create_subscription(PoseStamped, GOAL_TOPIC, self._on_goal, 10)

    # -- inputs ------------------------------------------------------------------------------
    def _at(self, stamp: Time, kind: str, apply: Callable[[], None]) -> None:
        """Apply ``apply`` when the drawing reaches ``stamp`` (``kind`` breaks ties, as
        EVENT_ORDER says; two of one kind and stamp come from one publisher, in its order)."""
        self.handled += 1
        self._sequence += 1
        heapq.heappush(self._events, (stamp_ns(stamp), EVENT_ORDER[kind], self._sequence, apply))

    def _report(self) -> None:
        self.lockstep.report(Ack(self.get_name(), None,
                                 capture_handled_ns=self._capture_handled_ns,
                                 command_handled_ns=self._command_handled_ns))

    def _handled_capture(self, stamp: Time) -> None:
        self._capture_handled_ns = max(self._capture_handled_ns, stamp_ns(stamp))
        self._report()

    def _on_odometry(self, data: bytes) -> None:
        sec, nanosec, x, y, qz, qw, *_ = self._odometry.decode(data)
        stamp = Time(sec=int(sec), nanosec=int(nanosec))
        at = stamp_ns(stamp)
        self._poses.append((at, stamp, (x, y, quaternion_to_yaw(qz, qw))))
        self.handled += 1
        # A sample is drawn when it is the first of a publish period (a whole number of
        # periods from time 0), whatever the rate of the stream.
        periods = (at // self.publish_ns, at // self.refresh_ns)
        if self._last_periods is not None and periods[0] <= self._last_periods[0]:
            return
        everything = self._last_periods is None or periods[1] > self._last_periods[1]
        self._last_periods = periods
        self._due.append((at, everything))
        self._draw_ready()

    def _draw_ready(self) -> None:
        while len(self._due) > DRAW_LAG_ARRAYS:
            due = self._due[0][0]
            if len(self._due) > DRAW_LAG_ARRAYS + MAX_HELD_ARRAYS:
                if not self._held_too_long:
                    self._held_too_long = True
                    self.get_logger().warning(
                        f'drawing at {due * 1e-9:.3f} s without waiting further for '
                        f'{self._wheel_streams_behind(due)}: they are '
                        f'{MAX_HELD_ARRAYS} arrays behind the odometry')
            elif self._wheel_streams_behind(due):
                return
            self._draw_until(*self._due.popleft())

    def _wheel_streams_behind(self, due: int) -> list[str]:
        """The wheel streams that have a publisher and have not yet delivered a sample stamped
        at ``due`` or later (a writer delivers in order: then every earlier one is in)."""
        return [topic for topic, reader in self._wheel_streams.items()
                if self._newest_wheel_ns.get(topic, -1) < due
                and reader.get_publisher_count() > 0]

    def finish(self) -> None:
        """At shutdown: publish the arrays already due, as the next odometry would have (so a
        run's arrays do not depend on how many ticks ran before it was stopped)."""
        while self._due and self.context.ok():
            self._draw_until(*self._due.popleft())

    def _draw_until(self, due: int, everything: bool) -> None:
        while self._poses and self._poses[0][0] <= due:
            _, self._stamp, (x, y, phi) = self._poses.pop(0)
            while self._events and self._events[0][0] <= stamp_ns(self._stamp):
                heapq.heappop(self._events)[3]()
            self.scene.on_odometry(x, y, phi)
        slips = [stamp for stamp in self._slips if stamp <= due]
        if slips:
            slip = deserialize_message(self._slips[max(slips)], JointState)
            self.scene.on_slip(*slip_of(slip.name, slip.velocity))
            for stamp in slips:
                del self._slips[stamp]
        joint_stamps = [stamp for stamp in self._joint_states if stamp <= due]
        if joint_stamps:
            joints = deserialize_message(self._joint_states[max(joint_stamps)], JointState)
            if STEERING_JOINT in joints.name:
                self.scene.on_steering(joints.position[joints.name.index(STEERING_JOINT)])
            for stamp in joint_stamps:
                del self._joint_states[stamp]
        if everything:
            self._publish(self.scene.robot_shapes() + self.scene.route_shapes(only_last=False)
                          + self.scene.static_shapes())
        else:
            shapes = self.scene.robot_shapes() + self.scene.route_shapes(only_last=True)
            if self._changed:
                shapes += self.scene.static_shapes(frozenset(self._changed), newest_only=True)
            self._publish(shapes)

    def _on_slip(self, data: bytes) -> None:
        self._take_wheel_sample(WHEEL_SLIP_TOPIC, self._slips, data)

    def _on_joint_state(self, data: bytes) -> None:
        self._take_wheel_sample(JOINT_STATES_THROTTLE_TOPIC, self._joint_states, data)

    def _take_wheel_sample(self, topic: str, samples: dict[int, bytes], data: bytes) -> None:
        self.handled += 1
        at = header_stamp_ns(data)
        samples[at] = data     # decoded only if drawn
        self._newest_wheel_ns[topic] = max(at, self._newest_wheel_ns.get(topic, at))
        self._draw_ready()

    def _on_trajectory(self, msg: JointTrajectory) -> None:
        self._command_handled_ns = stamp_ns(msg.header.stamp)
        try:
            self._take_trajectory(msg)
        finally:
            self._report()

    def _take_trajectory(self, msg: JointTrajectory) -> None:
        if len(msg.points) < 2 or STEERING_JOINT not in msg.joint_names:
            self.handled += 1
            return    # a stop: nothing to draw
        steering, length = move_of(msg.joint_names, msg.points[0].positions,
                                   msg.points[-1].positions, self.scene.robot.wheel_radius_m)

        def start_move() -> None:
            # The move's arrow (what was commanded) appears at the command's start; the wheels
            # turn as /joint_states says they do.
            self.scene.on_move(steering, length)
            self._changed.add('moves')
        self._at(msg.header.stamp, 'move', start_move)

    def _on_goal(self, msg: PoseStamped) -> None:
        def set_goal() -> None:
            self.scene.on_goal(msg.pose.position.x, msg.pose.position.y)
            self._changed.add('goal')
        self._at(msg.header.stamp, 'goal', set_goal)

    def _capture_reader(self, camera: str) -> Callable[[PoseStamped], None]:
        def on_capture(msg: PoseStamped) -> None:
            def add() -> None:
                self.scene.on_capture(camera, msg.pose.position.x, msg.pose.position.y)
                self._changed.add('captures')
            self._at(msg.header.stamp, camera, add)
            self._handled_capture(msg.header.stamp)
        return on_capture

    def _capture_with_uncertainty_reader(
            self, camera: str) -> Callable[[PoseWithCovarianceStamped], None]:
        def on_capture(msg: PoseWithCovarianceStamped) -> None:
            x, y = msg.pose.pose.position.x, msg.pose.pose.position.y
            try:
                radius = CaptureUncertainty.from_covariance(msg.pose.covariance).radius_95_m
            except ValueError as error:   # as the controller: ignored, said
                self.get_logger().warning(f'not drawn: {camera} capture: {error}',
                                          throttle_duration_sec=5.0)
                self.handled += 1
                self._handled_capture(msg.header.stamp)
                return

            def add() -> None:
                self.scene.on_capture(camera, x, y)
                self.scene.on_capture_uncertainty(camera, x, y, radius)
                self._changed.add('captures')
            self._at(msg.header.stamp, camera, add)
            self._handled_capture(msg.header.stamp)
        return on_capture

    def _publish(self, shapes: list[Shape]) -> None:
        self._changed.clear()
        cleared = self.scene.cleared
        if cleared:
            # The last goal's captures and moves go; everything still drawn is sent again.
            self.scene.cleared = False
            shapes = (self.scene.robot_shapes() + self.scene.route_shapes(only_last=False)
                      + self.scene.static_shapes())
        self.publisher.publish(self._encoder.encode(
            shapes, (self._stamp.sec, self._stamp.nanosec), clear_first=cleared))


# It may lag behind the odometry: it draws what is queued before it leaves.
COMPONENT = NodeComponent(MarkersNode, config_errors=(CameraConfigError,),
                          drain=lambda node: node.handled, on_shutdown=MarkersNode.finish)


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
