"""QoS of the graph's topics, in one place for every node and tool so they match (their names:
:mod:`omni_micro_common.topic_names`).

All reliable: a lost sample would change what the camera and the controller decide. Sample
streams keep 1000 (20 s of simulated time at the default grid) so that a reader a few hundred
samples behind at a high real-time factor loses none; statuses are latched.
"""

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy


def profile(depth: int, latched: bool = False, best_effort: bool = False) -> QoSProfile:
    """Keep-last ``depth``, reliable unless ``best_effort`` (a reader that meets any writer,
    REP-2003), transient-local when ``latched``: every profile of the graph and its tools."""
    return QoSProfile(depth=depth,
                      reliability=(ReliabilityPolicy.BEST_EFFORT if best_effort
                                   else ReliabilityPolicy.RELIABLE),
                      durability=(DurabilityPolicy.TRANSIENT_LOCAL if latched
                                  else DurabilityPolicy.VOLATILE))


def latched(depth: int) -> QoSProfile:
    """Transient-local: a subscriber that comes later still gets the last ``depth`` messages."""
    return profile(depth, latched=True)


STATUS_QOS = latched(10)
DATA_QOS = profile(1000)
# /lockstep: reports are small and every one counts (the robot waits for them): as the data.
LOCKSTEP_QOS = DATA_QOS
CAPTURE_QOS = profile(100)
# Camera images: a megabyte each, so a short history (in lockstep no more than the lead's worth
# are ever unhandled). camera_node offers reliable; tracker_node reads best effort by default
# (REP-2003: it then meets any driver) and reliable in the lockstep graph.
IMAGE_QOS = profile(10)
# A CameraInfo is half a kilobyte: its reader keeps seconds of them beside the images' short
# history, so that a reader starved of CPU for a while still knows of every frame sent (a frame
# read best effort and lost leaves its CameraInfo). With depth 10, a preflight beside two busy
# processes and two other test workers had no trace of three frames or more, and counted the
# driver's rate short (7.96 Hz for 8.21-8.73).
CAMERA_INFO_DEPTH = 100


def camera_info_profile(image_profile: QoSProfile) -> QoSProfile:
    """A CameraInfo reader's profile beside an image reader's: the same, CAMERA_INFO_DEPTH
    deep."""
    return QoSProfile(depth=CAMERA_INFO_DEPTH, reliability=image_profile.reliability,
                      durability=image_profile.durability)


# For the endpoints used every tick: rclpy gives each publisher and subscription two QoS event
# handlers by default (incompatible QoS or type), and every handler is one more entity the
# executor rebuilds its wait set with, on each wake-up: a third of the per-tick cost (profile in
# the README). Their QoS is fixed here for every node and tool, so they cannot be incompatible
# with each other; the latched and command topics, which outside tools join, keep the warnings.
# Pass as event_callbacks=... to create_publisher / create_subscription.
PER_TICK_PUBLISHER_EVENTS = PublisherEventCallbacks(use_default_callbacks=False)
PER_TICK_SUBSCRIPTION_EVENTS = SubscriptionEventCallbacks(use_default_callbacks=False)
