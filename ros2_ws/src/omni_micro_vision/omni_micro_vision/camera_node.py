"""ROS 2 adapter of the rendered cameras: the robot as images, from /odom, as a driver streams.

Subscribes /odom (the robot's true motion) and publishes, for each camera of ``cameras``, a
sensor_msgs/Image (mono8 or mono16) and its CameraInfo at ``frame_rate_hz`` of simulated time,
whether or not the robot moves, each stamped with its exposure's start:
  /camera/<name>/image_raw, /camera/<name>/camera_info      (frame ``<name>_optical_frame``)
  /lockstep            its report after each odometry sample, naming the frames it published
Frame k of camera c is rendered from the odometry sample that ends at or after its stamp, with
noise seeded by (seed, c, k): the same run gives the same frames at any speed
(:mod:`omni_micro_vision.exposure_schedule`). What a frame shows is
:func:`omni_micro_vision.rendering.render_robots`'s; this node only moves numbers.

With ``robots`` (a fleet's namespaces, ``robot_k`` carrying fiducial code k, as
``tracker_node`` reads them) it subscribes each robot's ``/robot_k/odom`` and every frame shows
every robot with its code, once every robot's odometry has reached the frame's time.

Each camera is mounted as a real one is (:class:`omni_micro_vision.optics.CameraOptics`): where
it looks (``center_m``), its pixels (``resolution_px`` over ``field_m``), any turn
(``yaw_rad``), a mirrored image (``mirrored``), a lens (``working_distance_m`` sets K,
``distortion`` is [k1, k2]); the CameraInfo states K, D, R and P. With ``scene: chessboard`` or
``circles`` the cameras show a calibration target (``target.*``) instead of the robot: the frames
``omni-micro calibrate-camera`` reads (``omni-micro record-target`` records them).

``image_readers`` (node names; empty by default) are the nodes that must not miss a frame: the
node reads /odom, and so lets the robot's clock start, only once its image writers have matched
their readers (docs/time.md).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.publisher import Publisher
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_common.conventions import join_stamp, quaternion_to_yaw, split_stamp
from omni_micro_common.lockstep import Ack
from omni_micro_common.lockstep_reporting import LockstepReporter
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.qos import DATA_QOS, IMAGE_QOS, PER_TICK_SUBSCRIPTION_EVENTS
from omni_micro_common.reader_matching import node_list_parameter, when_readers_matched
from omni_micro_common.tick_messages import robot_odometry_template
from omni_micro_common.topic_names import CAPTURE_TOPICS, ODOM_TOPIC, namespaced_topic
from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import CaptureRule, checked_cameras
from omni_micro_vision.camera_frames import SCENES, CameraFrames, camera_settings, target_settings
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.exposure_schedule import ExposureSchedule
from omni_micro_vision.fleet_tracking import robot_codes
from omni_micro_vision.rendering import InView


@dataclass(frozen=True)
class _Stream:
    """One camera's stream: what it sees with, and where its frames go."""

    frames: CameraFrames
    image_pub: Publisher
    info_pub: Publisher



class CameraNode(Node):
    def __init__(self, **node_options: Any) -> None:
        # node_options (context, parameter_overrides, ...) as rclpy's Node takes them: tests
        # build the node in-process with them.
        super().__init__('camera_node', **node_options)
        self.seed = int(self.declare_parameter('seed', 0).value)
        self.rate_hz = float(self.declare_parameter('frame_rate_hz',
                                                    CaptureRule.frame_rate_hz).value)
        if not (math.isfinite(self.rate_hz) and self.rate_hz > 0):
            raise CameraConfigError(f'frame_rate_hz must be > 0, got {self.rate_hz}')
        chosen = checked_cameras(list(self.declare_parameter('cameras',
                                                             ['macro', 'micro']).value or []))
        scene = self.declare_parameter('scene', 'robot').value
        if scene not in SCENES:
            raise CameraConfigError(f'scene must be one of {list(SCENES)}, got {scene!r}')
        target = target_settings('chessboard' if scene == 'robot' else scene, self._setting)
        self.streams: list[_Stream] = []
        for index, name in enumerate(CAPTURE_TOPICS):
            frames = CameraFrames(index, *camera_settings(name, self._setting), self.seed,
                                  None if scene == 'robot' else target)
            if name not in chosen:
                continue
            self.streams.append(_Stream(
                frames, self.create_publisher(Image, f'/camera/{name}/image_raw', IMAGE_QOS),
                self.create_publisher(CameraInfo, f'/camera/{name}/camera_info', IMAGE_QOS)))
            # Before the lockstep can start time: its first frame is then no slower than the rest.
            frames.warm_up()
        # The nodes whose image readers must be matched before the first frame: a frame sent
        # before would be lost to them (reliable, volatile), and a tracker in the lockstep would
        # never report it, so time would stand still. Until then there is no /odom reader, and
        # the robot's clock (which waits for that reader) does not start.
        self.image_readers = node_list_parameter(self, 'image_readers')
        codes = robot_codes(node_list_parameter(self, 'robots'))
        if codes and scene != 'robot':
            raise CameraConfigError(f'robots: only with scene robot (a calibration target is '
                                    f'one), got scene {scene!r}')
        # Each robot's odometry topic and code; one robot's /odom, uncoded, without robots.
        names = list(codes) or ['']
        self.sources: list[tuple[str, int | None]] = [
            (namespaced_topic(name, ODOM_TOPIC), codes.get(name)) for name in names]
        self._odometry = [robot_odometry_template(name) for name in names]
        self.schedule = ExposureSchedule(self.rate_hz, [code for _, code in self.sources])
        self._latest_ns: list[int | None] = [None] * len(self.sources)   # each robot's sample
        self.lockstep = LockstepReporter(self)
        self.get_logger().info(f'streaming {", ".join(chosen)} at {self.rate_hz:g} Hz of '
                               f'simulated time, seed {self.seed}'
                               + (f', {len(codes)} robots ({", ".join(codes)})' if codes else ''))
        when_readers_matched(self, [(stream.image_pub, self.image_readers)
                                    for stream in self.streams], self._subscribe)

    def _subscribe(self) -> None:
        # Raw, read in place (tick_messages): the per-tick message without its conversion.
        for robot, (topic, _) in enumerate(self.sources):
            self.create_subscription(Odometry, topic,
                                     functools.partial(self._on_odometry, robot=robot),
                                     DATA_QOS, raw=True,
                                     event_callbacks=PER_TICK_SUBSCRIPTION_EVENTS)

    def _on_odometry(self, data: bytes, robot: int = 0) -> None:
        sec, nanosec, x, y, qz, qw, forward, lateral, omega = self._odometry[robot].decode(data)
        now_s = join_stamp(int(sec), int(nanosec))
        phi = quaternion_to_yaw(qz, qw)
        # The twist is in the robot's frame (REP-103); the renderer wants the platform's.
        state = RobotState(x, y, phi, forward * math.cos(phi) - lateral * math.sin(phi),
                           forward * math.sin(phi) + lateral * math.cos(phi), omega)
        # Every frame whose exposure starts by now (at 30 Hz on a 50 Hz grid, at most one a
        # sample), once every robot's sample has reached it.
        published = [self._publish_frame(number, robots)
                     for number, robots in self.schedule.on_sample(robot, now_s, state)]
        self._latest_ns[robot] = int(sec) * 1_000_000_000 + int(nanosec)
        known = [stamp for stamp in self._latest_ns if stamp is not None]
        if len(known) < len(self._latest_ns):
            return   # no frame before every robot's first sample, and nothing processed
        # Last: the frames are out before the robot may move on. Processed: as far as every
        # robot's samples have come.
        self.lockstep.report(Ack(self.get_name(), min(known),
                                 frames_ns=(published[0], published[-1]) if published else None))

    def _setting(self, name: str, default: object) -> Any:
        return self.declare_parameter(name, default).value

    def _publish_frame(self, number: int, robots: list[InView]) -> int:
        """Publish frame ``number`` of every camera; returns its stamp in nanoseconds."""
        sec, nanosec = split_stamp(number / self.rate_hz)
        for stream in self.streams:
            info, image = stream.frames.messages(number, sec, nanosec, robots)
            stream.info_pub.publish(info)
            stream.image_pub.publish(image)
        return sec * 1_000_000_000 + nanosec


COMPONENT = NodeComponent(CameraNode, config_errors=(CameraConfigError,))


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
