"""ROS 2 adapter of the rendered cameras: the robot as images, from /odom, as a driver streams.

Subscribes /odom (the robot's true motion) and publishes, for each camera of ``cameras``, a
sensor_msgs/Image (mono8 or mono16) and its CameraInfo at ``frame_rate_hz`` of simulated time,
whether or not the robot moves, each stamped with its exposure's start:
  /camera/<name>/image_raw, /camera/<name>/camera_info      (frame ``<name>_optical_frame``)
  /lockstep            its report after each odometry sample, naming the frames it published
Frame k of camera c is rendered from the odometry sample that ends at or after its stamp, with
noise seeded by (seed, c, k): the same run gives the same frames at any speed. What a frame
shows is :func:`omni_micro_vision.rendering.render`'s; this node only moves numbers.

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
from omni_micro_common.tick_messages import odometry_template
from omni_micro_common.topic_names import CAPTURE_TOPICS, ODOM_TOPIC
from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import CaptureRule, checked_cameras
from omni_micro_vision.camera_frames import SCENES, CameraFrames, camera_settings, target_settings
from omni_micro_vision.errors import CameraConfigError


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
        self._next_frame = 0
        self._last_sample: tuple[float, RobotState] | None = None
        self.lockstep = LockstepReporter(self)
        self.get_logger().info(f'streaming {", ".join(chosen)} at {self.rate_hz:g} Hz of '
                               f'simulated time, seed {self.seed}')
        when_readers_matched(self, [(stream.image_pub, self.image_readers)
                                    for stream in self.streams], self._subscribe)

    def _subscribe(self) -> None:
        # Raw, read in place (tick_messages): the per-tick message without its conversion.
        self._odometry = odometry_template()
        self.create_subscription(Odometry, ODOM_TOPIC, self._on_odometry, DATA_QOS, raw=True,
                                 event_callbacks=PER_TICK_SUBSCRIPTION_EVENTS)

    def _on_odometry(self, data: bytes) -> None:
        sec, nanosec, x, y, qz, qw, forward, lateral, omega = self._odometry.decode(data)
        now_s = join_stamp(int(sec), int(nanosec))
        phi = quaternion_to_yaw(qz, qw)
        # The twist is in the robot's frame (REP-103); the renderer wants the platform's.
        state = RobotState(x, y, phi, forward * math.cos(phi) - lateral * math.sin(phi),
                           forward * math.sin(phi) + lateral * math.cos(phi), omega)
        # Every frame whose exposure starts by this sample (at 30 Hz on a 50 Hz grid, at most
        # one), showing the robot where it was when the exposure started: between the last
        # sample and this one (linear: at most a * dt^2 / 8, 4 nm at the motors' acceleration
        # over the 20 ms grid). Frames long past (a node started late) are not made up.
        self._next_frame = max(self._next_frame, math.floor(now_s * self.rate_hz + 1e-9))
        published = []
        while self._next_frame / self.rate_hz <= now_s + 1e-9:
            frame_s = self._next_frame / self.rate_hz
            published.append(self._publish_frame(self._next_frame,
                                                 self._state_at(frame_s, now_s, state)))
            self._next_frame += 1
        self._last_sample = (now_s, state)
        # Last: the frames are out before the robot may move on.
        self.lockstep.report(Ack(self.get_name(), int(sec) * 1_000_000_000 + int(nanosec),
                                 frames_ns=(published[0], published[-1]) if published else None))

    def _state_at(self, time_s: float, now_s: float, state: RobotState) -> RobotState:
        """The robot at ``time_s`` (at or before ``now_s``), between the last sample and
        ``state``."""
        if self._last_sample is None or time_s >= now_s or self._last_sample[0] >= now_s:
            return state
        before_s, before = self._last_sample
        share = max(0.0, (time_s - before_s) / (now_s - before_s))
        values = [a + share * (b - a) for a, b in zip(before.as_array(), state.as_array(),
                                                      strict=True)]
        values[2] = before.phi_rad + share * math.remainder(state.phi_rad - before.phi_rad,
                                                            2 * math.pi)
        return RobotState(*map(float, values))

    def _setting(self, name: str, default: object) -> Any:
        return self.declare_parameter(name, default).value

    def _publish_frame(self, number: int, state: RobotState) -> int:
        """Publish frame ``number`` of every camera; returns its stamp in nanoseconds."""
        sec, nanosec = split_stamp(number / self.rate_hz)
        for stream in self.streams:
            info, image = stream.frames.messages(number, sec, nanosec, state)
            stream.info_pub.publish(info)
            stream.image_pub.publish(image)
        return sec * 1_000_000_000 + nanosec


COMPONENT = NodeComponent(CameraNode, config_errors=(CameraConfigError,))


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()
