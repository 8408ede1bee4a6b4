"""Readers a node must have matched before it acts: a sample sent to a reliable, volatile reader
before the match is lost to it (discovery runs each way at its own pace)."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable

from rcl_interfaces.msg import ParameterDescriptor, ParameterType
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy
from rclpy.timer import Timer

from omni_micro_common.lockstep_groups import qualified_node_name


def node_list_parameter(node: Node, name: str) -> list[str]:
    """A read-only list of node names (empty by default: ROS has no empty-list default)."""
    descriptor = ParameterDescriptor(read_only=True, type=ParameterType.PARAMETER_STRING_ARRAY)
    return [value for value in node.declare_parameter(name, [''], descriptor).value or []
            if value]


def unmatched_readers(node: Node, publisher: Publisher, reader_nodes: list[str]) -> list[str]:
    """Which of ``reader_nodes``' readers of ``publisher``'s topic it has not matched yet
    (each named as :func:`~omni_micro_common.lockstep_groups.qualified_node_name` says).

    A sample sent before a reliable, volatile reader is matched is lost to that reader; seeing
    the reader in the ROS graph is not enough (discovery between two peers completes at its own
    pace, slower on a busy machine), so the publisher must count it. Transient-local readers
    (a user's tool, say) never match a volatile writer and are not waited for; a
    transient-local writer matches both, and keeps only its last samples for a reader it
    matches late (a status of depth 1 published twice before the match reaches it once).
    """
    topic = publisher.topic_name
    latched = publisher.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    readers = [info for info in node.get_subscriptions_info_by_topic(topic)
               if latched or info.qos_profile.durability != DurabilityPolicy.TRANSIENT_LOCAL]
    return [f"{name}'s reader of {topic}" for name in reader_nodes
            if not any(qualified_node_name(info.node_namespace, info.node_name) == name
                       for info in readers)
            or publisher.get_subscription_count() < len(readers)]


def reader_census(node: Node, publisher: Publisher) -> str:
    """What ``node`` knows of the readers of ``publisher``'s topic, for a report of a wait that
    lasts: the readers the ROS graph shows, by node (a reader whose node's name has not come in
    yet is ``_NODE_NAMESPACE_UNKNOWN_/_NODE_NAME_UNKNOWN_``: rmw's ros_discovery_info did not
    reach this node), and how many of them the publisher has matched (DDS discovery)."""
    names = sorted(qualified_node_name(info.node_namespace, info.node_name)
                   for info in node.get_subscriptions_info_by_topic(publisher.topic_name))
    return (f'{publisher.topic_name}: the graph shows {len(names)} reader(s)'
            f'{" (" + ", ".join(names) + ")" if names else ""}, its writer matched '
            f'{publisher.get_subscription_count()}')


def missing_readers_report(node: Node, writers: list[tuple[Publisher, list[str]]]) -> str:
    """The named readers ``writers`` have not matched yet (:func:`unmatched_readers`, each
    publisher with the nodes named beside it), followed by what ``node`` knows of their topics
    (:func:`reader_census`, once a topic): what a wait that lasts says; '' when none is
    missing."""
    lacking = [(publisher, missing) for publisher, names in writers
               for missing in unmatched_readers(node, publisher, names)]
    if not lacking:
        return ''
    publishers = {publisher.topic_name: publisher for publisher, _ in lacking}
    census = '; '.join(reader_census(node, publishers[topic]) for topic in sorted(publishers))
    return f'{", ".join(missing for _, missing in lacking)} ({census})'


# How often a node that waits for readers (when_readers_matched) looks again, and after how
# long a wait it says what it waits for (then as often again): a wait that does not end holds
# the robot's clock at 0, and the log is where a hung run is read.
MATCH_POLL_S = 0.02
WAIT_REPORT_S = 5.0


def when_readers_matched(node: Node, writers: list[tuple[Publisher, list[str]]],
                         then: Callable[[], None]) -> None:
    """Call ``then`` once each publisher has matched the readers of the nodes named beside it
    (:func:`unmatched_readers`), at once if it already has. A node reads ``/odom`` only from
    ``then`` on, so that the robot's clock, which waits for that reader, starts no sooner: a
    sample of its own sent before would be lost to those readers. Polled on the steady clock,
    since /clock does not run yet."""
    def unmatched() -> list[str]:
        return [missing for publisher, names in writers
                for missing in unmatched_readers(node, publisher, names)]

    if not unmatched():
        then()
        return
    timer: Timer | None = None
    started = time.monotonic()
    reported = started

    def look_again() -> None:
        nonlocal timer, reported
        if timer is None:
            return
        if unmatched():
            if time.monotonic() - reported >= WAIT_REPORT_S:
                reported = time.monotonic()
                node.get_logger().warning(f'waiting {reported - started:.0f} s for '
                                          f'{missing_readers_report(node, writers)}')
            return
        timer.cancel()
        node.destroy_timer(timer)
        timer = None
        then()
    timer = node.create_timer(MATCH_POLL_S, look_again,
                              clock=Clock(clock_type=ClockType.STEADY_TIME))


def capture_reader_names(node: Node) -> tuple[list[str], list[str], list[str]]:
    """The nodes that must not miss a camera's captures, by the topics they read: its
    ``capture_readers`` (bare PoseStamped captures), ``covariance_readers`` (their
    PoseWithCovarianceStamped) and ``motion_readers`` (captures in motion: a servo, a recorder)
    parameters, which the orchestration sets from the nodes present and which are empty when
    the camera is started alone."""
    return (node_list_parameter(node, 'capture_readers'),
            node_list_parameter(node, 'covariance_readers'),
            node_list_parameter(node, 'motion_readers'))


def when_capture_readers_matched(node: Node, pose_publishers: Iterable[Publisher],
                                 covariance_publishers: Iterable[Publisher],
                                 motion_publishers: Iterable[Publisher],
                                 then: Callable[[], None],
                                 others: Iterable[tuple[Publisher, list[str]]] = ()) -> None:
    """:func:`when_readers_matched` for a camera's captures (vision_node, tracker_node), each
    publisher with the readers :func:`capture_reader_names` names for it, and ``others``."""
    pose_readers, covariance_readers, motion_readers = capture_reader_names(node)
    when_readers_matched(
        node, [(publisher, pose_readers) for publisher in pose_publishers]
        + [(publisher, covariance_readers) for publisher in covariance_publishers]
        + [(publisher, motion_readers) for publisher in motion_publishers] + list(others),
        then)
