"""The names of the graph's topics, defined once (plain strings: no rclpy, so that a command's
``--help`` can name them). Their types and QoS: docs/graph.md, "The node graph", and
:mod:`omni_micro_common.qos`.
"""

# The robot's clock and state, every grid tick (dynamics_node, or a real robot's driver).
CLOCK_TOPIC = '/clock'
ODOM_TOPIC = '/odom'
JOINT_STATES_TOPIC = '/joint_states'
WHEEL_SLIP_TOPIC = '/wheel_slip'
# The same as /odom and /joint_states on one tick in a few, for who only watches (topic_tools
# throttle's names).
ODOM_THROTTLE_TOPIC = '/odom_throttle'
JOINT_STATES_THROTTLE_TOPIC = '/joint_states_throttle'
# Commands to the robot's wheels, and the goals the controller is given (RViz's name).
WHEEL_TRAJECTORY_TOPIC = '/wheel_trajectory'
GOAL_TOPIC = '/goal_pose'
# The captures, per camera, bare and with their uncertainty (same stamp): the captures stay
# PoseStamped, so a driver that cannot estimate its own uncertainty still fits the contract (the
# controller then takes a fixed one from its params).
CAPTURE_TOPICS = {'macro': '/camera/macro/pose', 'micro': '/camera/micro/pose'}
CAPTURE_COVARIANCE_TOPICS = {'macro': '/camera/macro/pose_with_covariance',
                             'micro': '/camera/micro/pose_with_covariance'}
# Where a reader of the captures takes their uncertainty from (controller_node's and
# markers_node's capture_uncertainty): 'covariance' reads each capture from its
# CAPTURE_COVARIANCE_TOPICS message alone, which has the pose too; 'fixed' reads CAPTURE_TOPICS,
# for a camera driver that publishes bare PoseStamped captures.
CAPTURE_UNCERTAINTY_SOURCES = ('covariance', 'fixed')
# Captures of the moving robot (vision_node with captures_in_motion): each stamped at the middle
# of its exposure, with its uncertainty, beside the stationary captures above.
CAPTURE_IN_MOTION_TOPICS = {'macro': '/camera/macro/pose_in_motion',
                            'micro': '/camera/micro/pose_in_motion'}
# Latched statuses.
CONTROLLER_STATUS_TOPIC = '/controller/status'
# dynamics_node's, with several robots: two chassis touching, both named.
CONTACT_TOPIC = '/robot_contacts'
# The orchestration's, with several real robots on the bench: every robot stopped, and why (two
# too close, or one driving unnamed by the cameras), the robots named.
FLEET_GUARD_TOPIC = '/fleet_guard'
# tracker_node's, per camera: what its latest frame gave (or why it was refused), and, for frames
# stamped on the wall clock (a driver's), how old they are when they arrive.
TRACKER_STATUS_TOPICS = {'macro': '/camera/macro/tracker_status',
                         'micro': '/camera/micro/tracker_status'}
CAMERA_STATUS_TOPIC = '/camera/status'
RECORDER_STATUS_TOPIC = '/bag_recorder/status'
# What markers_node draws.
MARKERS_TOPIC = '/markers'
# Every topic that is a robot's own, remapped into its namespace in a fleet; /clock,
# /lockstep, /robot_contacts and /fleet_guard stay the graph's.
ROBOT_TOPICS = (ODOM_TOPIC, JOINT_STATES_TOPIC, WHEEL_SLIP_TOPIC, ODOM_THROTTLE_TOPIC,
                JOINT_STATES_THROTTLE_TOPIC, WHEEL_TRAJECTORY_TOPIC, GOAL_TOPIC,
                CONTROLLER_STATUS_TOPIC, CAMERA_STATUS_TOPIC, *CAPTURE_TOPICS.values(),
                *CAPTURE_COVARIANCE_TOPICS.values(), *CAPTURE_IN_MOTION_TOPICS.values(),
                *TRACKER_STATUS_TOPICS.values(), MARKERS_TOPIC)


def camera_info_beside(image_topic: str) -> str:
    """Where a camera driver publishes the CameraInfo of ``image_topic``: ``camera_info`` beside
    it (image_transport's convention)."""
    return image_topic.rsplit('/', 1)[0] + '/camera_info'


# A fleet's robot k lives in the namespace robot_k (its fiducial carries code k); the
# single robot is the fleet of one in the root namespace, its topics the bare names above.
ROBOT_NAMESPACE_PREFIX = 'robot_'


def robot_name(index: int) -> str:
    """Robot ``index``'s namespace: ``robot_1``."""
    return f'{ROBOT_NAMESPACE_PREFIX}{index}'


def robot_index(name: str) -> int | None:
    """The k of a namespace ``robot_k`` (None: not a robot's namespace)."""
    number = name.removeprefix(ROBOT_NAMESPACE_PREFIX)
    if number == name or not number.isdigit() or not number.isascii():
        return None
    return int(number)


def namespaced_topic(namespace: str, topic: str) -> str:
    """``/odom`` in namespace ``robot_1``: ``/robot_1/odom`` (the topic itself in the root
    namespace, the single robot's)."""
    return f'/{namespace}{topic}' if namespace else topic


def namespaced_frame(namespace: str, frame: str) -> str:
    """A frame of the robot in ``namespace``: ``robot_1/odom`` (REP-105 per robot; the frame
    itself in the root namespace)."""
    return f'{namespace}/{frame}' if namespace else frame


def robot_topic(index: int, topic: str) -> str:
    """Robot ``index``'s ``topic``: ``/robot_1/odom``."""
    return namespaced_topic(robot_name(index), topic)


def is_plain_name(name: str) -> bool:
    """One ROS name token (letters, digits and _, a letter first): what a fleet robot's
    namespace must be (``robot_1``), whose topics are then ``/robot_1/odom``, ..."""
    return name[:1].isalpha() and name.replace('_', 'a').isalnum()
