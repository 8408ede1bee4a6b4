"""The preflight's ears: a node in the bench's domain that reads each camera's frames and
CameraInfo best effort (as tracker_node does, so that what it loses the tracker would lose) and
each robot's joint states, then asks the ROS graph what QoS their publishers offer, and names
the robots of several in each camera's last frame as tracker_node would
(:mod:`omni_micro_bringup.preflight` judges what it heard)."""

from __future__ import annotations

import time
from collections.abc import Callable

import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image, JointState

from omni_micro_bringup.preflight import CameraWatch, Offered, RobotWatch
from omni_micro_common.conventions import stamp_ns
from omni_micro_common.installed import use_dds_profile
from omni_micro_common.qos import IMAGE_QOS, camera_info_profile
from omni_micro_common.topic_names import robot_name
from omni_micro_vision.tracked_camera import TrackedCamera

NODE_NAME = 'omni_micro_preflight'
# How many joint states the preflight's reader keeps (5 s of joint_state_broadcaster's 50 Hz): a
# driver's rate is counted from the states that came. With 10 kept, a preflight beside busy
# processes and two other test workers counted a stand-in driver's 50 Hz (it stamps every state
# on its grid, sending late ones in a burst) as 45.4 Hz; not seen again in 4 runs beside four
# busy processes, so that its queue was the cause is likely, not shown.
STATES_KEPT = 250


def listen(cameras: list[CameraWatch], robots: list[RobotWatch], seconds: float,
           domain_id: int | None, tracked: dict[str, TrackedCamera] | None = None,
           robot_names: list[str] | None = None,
           progress: Callable[[float], None] | None = None) -> None:
    """Listen ``seconds`` to every camera and robot; then note their publishers' QoS and (with
    ``robot_names`` and ``tracked``, each camera as the tracker maps it) who each camera's last
    frame names."""
    use_dds_profile()   # as the tracker and the controller of a run have it
    context = Context()
    rclpy.init(context=context, domain_id=domain_id)
    node = rclpy.create_node(NODE_NAME, context=context)
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    last_frames: dict[str, bytes] = {}
    best_effort = QoSProfile(depth=IMAGE_QOS.depth, reliability=ReliabilityPolicy.BEST_EFFORT)
    try:
        for camera in cameras:
            def on_image(data: bytes, camera: CameraWatch = camera) -> None:
                from omni_micro_vision.image_messages import read_image

                arrived = time.time_ns()
                msg = read_image(data)
                camera.on_frame(stamp_ns(msg.header.stamp), arrived, str(msg.encoding),
                                int(msg.width), int(msg.height), len(data))
                last_frames[camera.name] = data

            def on_info(msg: CameraInfo, camera: CameraWatch = camera) -> None:
                camera.on_info(stamp_ns(msg.header.stamp), int(msg.width), int(msg.height),
                               list(msg.k))

            node.create_subscription(Image, camera.image_topic, on_image, best_effort,
                                     raw=True)
            node.create_subscription(CameraInfo, camera.info_topic, on_info,
                                     camera_info_profile(best_effort))
        for robot in robots:
            def on_state(msg: JointState, robot: RobotWatch = robot) -> None:
                robot.on_state(stamp_ns(msg.header.stamp), list(msg.name))

            # Best effort meets either kind of driver; what it offers is judged below.
            node.create_subscription(JointState, robot.topic, on_state,
                                     QoSProfile(depth=STATES_KEPT,
                                                reliability=ReliabilityPolicy.BEST_EFFORT))
        started = time.monotonic()
        while (elapsed := time.monotonic() - started) < seconds:
            executor.spin_once(timeout_sec=0.05)
            if progress is not None:
                progress(elapsed)
        for camera in cameras:
            camera.offered = _offered(node, camera.image_topic)
        for robot in robots:
            robot.offered = _offered(node, robot.topic)
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=context)
    if robot_names and tracked:
        for camera in cameras:
            if camera.name in last_frames and camera.name in tracked:
                camera.named = _named(last_frames[camera.name], tracked[camera.name],
                                      robot_names)


def _offered(node: rclpy.node.Node, topic: str) -> list[Offered]:
    return [Offered(info.node_name, info.qos_profile.reliability.name.lower(),
                    info.qos_profile.durability.name.lower())
            for info in node.get_publishers_info_by_topic(topic)
            if info.node_name != NODE_NAME]


def _named(data: bytes, camera: TrackedCamera, robots: list[str]) -> dict[str, str]:
    """Each robot: 'named' if the frame names it by its code, else why not."""
    from omni_micro_vision.code_reading import identify
    from omni_micro_vision.encodings import full_scale
    from omni_micro_vision.errors import CameraConfigError
    from omni_micro_vision.fleet_tracking import robot_codes
    from omni_micro_vision.image_messages import image_array, read_image

    codes = robot_codes(robots)
    try:
        pixels = image_array(read_image(data), camera.plane.resolution_px)
        sightings, reason = identify(pixels, camera.plane, full_scale(pixels, camera.bit_depth))
    except CameraConfigError as error:
        return {robot: f'frame refused: {error}' for robot in robots}
    seen = {robot_name(s.robot) for s in sightings if s.robot is not None}
    unnamed = sorted({s.reason for s in sightings if s.robot is None})
    why = '; '.join(unnamed) or reason or 'not in the frame'
    return {robot: 'named' if robot in seen else why for robot in codes}
