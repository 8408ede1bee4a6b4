"""Who publishes and who subscribes each topic of the graph, with which type and QoS, as rqt_graph
would show it: the graph brought up with its clock paused, read from discovery, and stopped."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, cast

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.graph import brought_up, driver_for
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_common.lockstep_groups import qualified_node_name
from omni_micro_sim.dynamics_parameters import awaited_readers


@dataclass(frozen=True)
class Endpoint:
    """A publisher or subscriber as discovery shows it (the history depth is not discovered)."""

    node: str
    reliability: str      # reliable / best_effort
    durability: str       # volatile / transient_local


@dataclass(frozen=True)
class TopicEndpoints:
    topic: str
    msgtype: str
    publishers: tuple[Endpoint, ...]
    subscribers: tuple[Endpoint, ...]


# Discovery of the last endpoints after the readers the robot's clock waits for.
GRAPH_SETTLE_S = 1.0
# How long those readers may take to be seen once the graph is up.
READERS_SEEN_WITHIN_S = 30.0


# Every ROS 2 node has these; they say nothing about this graph.
_INFRASTRUCTURE_TOPICS = ('/rosout', '/parameter_events')


def describe_graph(options: GraphOptions) -> list[TopicEndpoints]:
    """Bring the graph of ``options`` up (one robot's, or with ``options.fleet`` each robot's
    under its namespace; its clock paused, no goal), read from the ROS graph who publishes and
    who subscribes each topic with which type and QoS, as rqt_graph would, and stop it. The
    orchestrator's own node is in it: it sends the goals and reads statuses."""
    driver = driver_for(options)
    with brought_up(options, driver) as (graph, _):
        monitor = driver.monitor
        assert monitor is not None
        # Every endpoint seen, not only the readers the start waits for (readiness): first,
        # by name, each reader the robot's clock waits for (dynamics_node's awaited_readers;
        # a node may subscribe only once its own writers have matched, vision_node to /odom
        # among them), then whatever else comes.
        entries = [str(entry) for process in graph.processes
                   for spec in (process.spec.hosts or (process.spec,))
                   for entry in cast(list, spec.overrides.get('awaited_readers', []))]
        awaited = awaited_readers(entries)
        deadline = time.monotonic() + READERS_SEEN_WITHIN_S
        while unseen := [f'{name}:{topic}' for name, topics in awaited.items()
                         for topic in topics if not _reader_seen(monitor.node, name, topic)]:
            graph.check_alive()
            if time.monotonic() > deadline:
                raise RunFailed(f'readers not seen within {READERS_SEEN_WITHIN_S:g} s: '
                                f'{", ".join(unseen)}; logs in {graph.log_dir}')
            monitor.spin_for(0.05)
        monitor.spin_for(GRAPH_SETTLE_S)
        node = monitor.node
        described = []
        for topic, types in sorted(node.get_topic_names_and_types()):
            if topic in _INFRASTRUCTURE_TOPICS:
                continue

            def endpoints(infos: list) -> tuple[Endpoint, ...]:
                return tuple(sorted(
                    (Endpoint(qualified_node_name(info.node_namespace, info.node_name),
                              info.qos_profile.reliability.name.lower(),
                              info.qos_profile.durability.name.lower())
                     for info in infos),
                    key=lambda e: e.node))

            publishers = endpoints(node.get_publishers_info_by_topic(topic))
            subscribers = endpoints(node.get_subscriptions_info_by_topic(topic))
            if publishers or subscribers:
                described.append(TopicEndpoints(topic, types[0], publishers, subscribers))
        return described


def _reader_seen(node: Any, name: str, topic: str) -> bool:
    """Whether discovery shows node ``name``'s reader of ``topic`` (``robot_1/vision_node``, as
    dynamics_node's awaited_readers name it)."""
    return any(qualified_node_name(info.node_namespace, info.node_name) == name
               for info in node.get_subscriptions_info_by_topic(topic))
