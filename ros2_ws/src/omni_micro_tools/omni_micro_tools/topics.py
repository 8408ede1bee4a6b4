"""What the graph's bags hold: each topic's type and the QoS its publisher offers.

Plain data (no rosbags import), so that a command can name the topics and storages in its
``--help`` without loading the bag library.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from omni_micro_common.topic_names import (
    CAMERA_STATUS_TOPIC,
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_IN_MOTION_TOPICS,
    CAPTURE_TOPICS,
    CLOCK_TOPIC,
    CONTROLLER_STATUS_TOPIC,
    FLEET_GUARD_TOPIC,
    GOAL_TOPIC,
    JOINT_STATES_TOPIC,
    MARKERS_TOPIC,
    ODOM_TOPIC,
    WHEEL_SLIP_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
    camera_info_beside,
    is_plain_name,
)

if TYPE_CHECKING:
    from rclpy.qos import QoSProfile
    from rosbags.interfaces import Qos

# rosbag2 storage plugins the recorder can write (mcap is Jazzy's default).
STORAGE_NAMES = ('mcap', 'sqlite3')


@dataclass(frozen=True)
class TopicSpec:
    msgtype: str
    depth: int
    latched: bool = False

    def reader_profile(self, depth: int | None = None, best_effort: bool = False) -> QoSProfile:
        """A reader's (or a replaying writer's) rclpy profile for the topic: its durability,
        the topic's depth unless ``depth``, reliable unless ``best_effort``."""
        from omni_micro_common.qos import profile

        return profile(self.depth if depth is None else depth, self.latched, best_effort)

    def qos(self) -> Qos:
        """The QoS the graph's publisher offers, as metadata.yaml records it (zero durations:
        rclpy's defaults, no deadline or lifespan)."""
        from rosbags.interfaces import (
            Qos,
            QosDurability,
            QosHistory,
            QosLiveliness,
            QosReliability,
            QosTime,
        )

        zero = QosTime(0, 0)
        durability = QosDurability.TRANSIENT_LOCAL if self.latched else QosDurability.VOLATILE
        return Qos(QosHistory.KEEP_LAST, self.depth, QosReliability.RELIABLE, durability,
                   zero, zero, QosLiveliness.AUTOMATIC, zero, False)


# Every topic of the graph (docs/graph.md, "The node graph"), but /odom_throttle and
# /joint_states_throttle: copies of /odom and /joint_states for markers_node, not recorded.
GRAPH_TOPICS: dict[str, TopicSpec] = {
    CLOCK_TOPIC: TopicSpec('rosgraph_msgs/msg/Clock', 1000),
    ODOM_TOPIC: TopicSpec('nav_msgs/msg/Odometry', 1000),
    JOINT_STATES_TOPIC: TopicSpec('sensor_msgs/msg/JointState', 1000),
    WHEEL_SLIP_TOPIC: TopicSpec('sensor_msgs/msg/JointState', 1000),
    WHEEL_TRAJECTORY_TOPIC: TopicSpec('trajectory_msgs/msg/JointTrajectory', 1000),
    **{topic: TopicSpec('geometry_msgs/msg/PoseStamped', 100)
       for topic in CAPTURE_TOPICS.values()},
    **{topic: TopicSpec('geometry_msgs/msg/PoseWithCovarianceStamped', 100)
       for topic in CAPTURE_COVARIANCE_TOPICS.values()},
    CAMERA_STATUS_TOPIC: TopicSpec('diagnostic_msgs/msg/DiagnosticStatus', 1, latched=True),
    GOAL_TOPIC: TopicSpec('geometry_msgs/msg/PoseStamped', 10),
    CONTROLLER_STATUS_TOPIC: TopicSpec('diagnostic_msgs/msg/DiagnosticStatus', 10, latched=True),
    MARKERS_TOPIC: TopicSpec('visualization_msgs/msg/MarkerArray', 1000),
}
# The rendered cameras' streams (run --vision images): recorded only when asked
# (--record-images), a megabyte a frame. Depth as omni_micro_common.qos.IMAGE_QOS.
IMAGE_TOPICS: dict[str, TopicSpec] = {
    f'/camera/{camera}/{stream}': TopicSpec(f'sensor_msgs/msg/{kind}', 10)
    for camera in ('macro', 'micro')
    for stream, kind in (('image_raw', 'Image'), ('camera_info', 'CameraInfo'))}
# Captures in motion: published only by a vision_node with captures_in_motion.
IN_MOTION_TOPICS: dict[str, TopicSpec] = {
    topic: TopicSpec('geometry_msgs/msg/PoseWithCovarianceStamped', 100)
    for topic in CAPTURE_IN_MOTION_TOPICS.values()}
# The orchestration's, with several real robots on the bench: why it stopped them all.
GUARD_TOPICS: dict[str, TopicSpec] = {
    FLEET_GUARD_TOPIC: TopicSpec('diagnostic_msgs/msg/DiagnosticStatus', 10, latched=True)}
RECORDABLE_TOPICS = {**GRAPH_TOPICS, **IMAGE_TOPICS, **IN_MOTION_TOPICS, **GUARD_TOPICS}


def robot_and_topic(topic: str) -> tuple[str, str]:
    """A fleet robot's namespace and the single robot's name of its topic:
    ``/robot_1/odom`` -> ``('robot_1', '/odom')``; a graph topic (``/clock``, ``/odom``) or any
    other name -> ``('', topic)``. /clock is the graph's, never a robot's."""
    if topic in RECORDABLE_TOPICS:
        return '', topic
    robot, separator, rest = topic[1:].partition('/')
    own = f'/{rest}'
    if topic.startswith('/') and separator and is_plain_name(robot) and own in RECORDABLE_TOPICS \
            and own != CLOCK_TOPIC:
        return robot, own
    return '', topic


def recordable_spec(topic: str) -> TopicSpec | None:
    """What the recorder records a topic as: a graph topic, or one robot's of a fleet
    (``/robot_k/odom``); None for a topic it cannot record."""
    return RECORDABLE_TOPICS.get(robot_and_topic(topic)[1])
# The types of the camera streams: a megabyte a frame, never held in memory while a bag is put
# in order, and read best effort from a driver outside the lockstep (REP-2003).
IMAGE_TYPES = ('sensor_msgs/msg/Image', 'sensor_msgs/msg/CameraInfo')


def driver_image_topics(image_topics: list[str]) -> dict[str, TopicSpec]:
    """A camera driver's image topics, any names, each with the CameraInfo beside it, as the
    recorder records them.

    Raises
    ------
    ValueError
        A topic that is not absolute.
    """
    topics: dict[str, TopicSpec] = {}
    for topic in image_topics:
        if not topic.startswith('/') or topic.endswith('/'):
            raise ValueError(f'expected absolute topic names (/camera/image_raw), got {topic!r}')
        topics[topic] = TopicSpec(IMAGE_TYPES[0], 10)
        topics[camera_info_beside(topic)] = TopicSpec(IMAGE_TYPES[1], 10)
    return topics

# Within one instant of simulated time a finished bag holds its topics in this order: what
# causes before what it causes (the robot's sample, the frames, the captures, the controller's
# answer, the drawing). Topics not named here come last. See omni_micro_tools.bag_order.
TOPIC_ORDER: tuple[str, ...] = (
    CLOCK_TOPIC, GOAL_TOPIC, ODOM_TOPIC, JOINT_STATES_TOPIC, WHEEL_SLIP_TOPIC,
    *(topic for camera in ('macro', 'micro')
      for topic in (f'/camera/{camera}/camera_info', f'/camera/{camera}/image_raw')),
    *(topic for camera in ('macro', 'micro')
      for topic in (f'/camera/{camera}/pose_with_covariance', f'/camera/{camera}/pose')),
    *CAPTURE_IN_MOTION_TOPICS.values(),
    CAMERA_STATUS_TOPIC, CONTROLLER_STATUS_TOPIC, WHEEL_TRAJECTORY_TOPIC, MARKERS_TOPIC,
    FLEET_GUARD_TOPIC)
assert set(TOPIC_ORDER) == set(RECORDABLE_TOPICS)
# A run's bag ends this long (simulated time) after its last outcome: the stop command and the
# samples of the robot coming to rest (a ramp down from cruise speed takes 0.17 s, from the tick
# after the stop), the same in every run of the same seed.
BAG_TAIL_S = 0.5
# The key of /bag_recorder/status saying how far (simulated seconds) the recorder has received
# every one of the robot's per-tick streams.
RECEIVED_UP_TO_KEY = 'received_up_to_s'
