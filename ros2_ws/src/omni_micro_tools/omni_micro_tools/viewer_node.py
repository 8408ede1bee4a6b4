"""The live view's node: the graph's topics, as they are, over the Foxglove WebSocket protocol.

Each topic becomes a Foxglove channel with ``cdr`` encoding and its type's ``ros2msg`` schema, so
Foxglove decodes them as it does from foxglove_bridge. It only listens, best effort: a viewer
never holds up a publisher, and the Foxglove SDK drops frames for a client that reads slowly.
The server advertises no capability: clients cannot publish, call services or set parameters.

Parameters (its section of omni_micro_bringup's ``config/omni_micro.yaml``): ``host`` (default
127.0.0.1: loopback only), ``port`` (default 8765; 0 for any free one), ``markers`` (serve
/markers; false for a graph without markers_node), ``robots`` (a fleet's namespaces:
each robot's topics under its own, ``/robot_k/markers``, ``/robot_k/odom``, ..., and the one
/clock). ``omni-micro view`` and ``run --view`` start it.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from typing import Any

from rclpy.node import Node
from rclpy.parameter import Parameter

from omni_micro_common.errors import ParameterError
from omni_micro_common.messages import message_class
from omni_micro_common.node_runtime import NodeComponent, run_component
from omni_micro_common.reader_matching import node_list_parameter
from omni_micro_common.topic_names import (
    CLOCK_TOPIC,
    MARKERS_TOPIC,
    is_plain_name,
    namespaced_topic,
)
from omni_micro_tools.bags import TYPESTORE
from omni_micro_tools.topics import GRAPH_TOPICS, TopicSpec

# The view serves every topic a bag of the graph holds.
VIEW_TOPICS = tuple(GRAPH_TOPICS)
# A client this many messages behind loses the oldest: the graph never waits for a viewer.
BACKLOG_MESSAGES = 1024


def ros2msg_schema(msgtype: str) -> bytes:
    """The ``ros2msg`` schema of a type: its definition and its dependencies', as rosbag2's MCAP
    files and foxglove_bridge give them."""
    text, _ = TYPESTORE.generate_msgdef(msgtype, ros_version=2)
    return text.encode()


class Viewer(Node):
    def __init__(self, **node_options: Any) -> None:
        import foxglove

        node_options['parameter_overrides'] = [
            Parameter('use_sim_time', value=True), *node_options.get('parameter_overrides', [])]
        super().__init__('omni_micro_viewer', **node_options)
        host = str(self.declare_parameter('host', '127.0.0.1').value)
        port = self.declare_parameter('port', 8765).value
        topics = view_topics(bool(self.declare_parameter('markers', True).value),
                             node_list_parameter(self, 'robots'))
        if isinstance(port, bool) or not isinstance(port, int) or not 0 <= port <= 65535:
            raise ParameterError(f'port must be a whole number in 0-65535, got {port!r}')
        self.forwarded = dict.fromkeys(topics, 0)
        self.channels: dict[str, Any] = {}
        for topic, spec in topics.items():
            self.channels[topic] = foxglove.Channel(
                topic, message_encoding='cdr',
                schema=foxglove.Schema(name=spec.msgtype, encoding='ros2msg',
                                       data=ros2msg_schema(spec.msgtype)))
            qos = spec.reader_profile(best_effort=True)
            self.create_subscription(message_class(spec.msgtype), topic,
                                     self._forwarder(topic), qos, raw=True)
        # Listening only once every channel exists: a client that connects as soon as the port
        # opens (a test's, a reconnecting Foxglove's) is offered them all at once; one offered
        # a channel while the viewer was still making them had its subscription to it refused
        # as "unknown channel" (seen on a busy machine: no /odom reached the client).
        try:
            self.server = foxglove.start_server(name='omni-micro', host=host, port=port,
                                                capabilities=[],
                                                message_backlog_size=BACKLOG_MESSAGES)
        except Exception:
            self._close_channels()
            raise
        self.get_logger().info(f'live view on ws://{host}:{self.server.port}')

    def _forwarder(self, topic: str) -> Callable[[bytes], None]:
        channel = self.channels[topic]

        def forward(data: bytes) -> None:
            channel.log(data, log_time=self.get_clock().now().nanoseconds)
            self.forwarded[topic] += 1
        return forward

    def stop(self) -> None:
        self.server.stop()
        self._close_channels()

    def _close_channels(self) -> None:
        # Channels outlive their server in the SDK's process-wide context: a viewer made later
        # in the same process (a container, a test) would offer these too.
        for channel in self.channels.values():
            channel.close()


def stop_and_report(viewer: Viewer) -> None:
    viewer.stop()
    print(f'live view stopped after forwarding {sum(viewer.forwarded.values())} messages',
          file=sys.stderr)


COMPONENT = NodeComponent(Viewer, on_shutdown=stop_and_report)


def main(args: list[str] | None = None) -> None:
    run_component(COMPONENT, args=args)


if __name__ == '__main__':
    main()


def view_topics(markers: bool = True, robots: list[str] | None = None) -> dict[str, TopicSpec]:
    """What the view serves: the graph's topics, or with ``robots`` each robot's under its
    namespace, robot by robot, and the one /clock.

    Raises
    ------
    ParameterError
        A robot's namespace that is not one ROS name token.
    """
    own = [topic for topic in VIEW_TOPICS if markers or topic != MARKERS_TOPIC]
    if not robots:
        return {topic: GRAPH_TOPICS[topic] for topic in own}
    strangers = [robot for robot in robots if not is_plain_name(robot)]
    if strangers:
        raise ParameterError(f'robots: {strangers} are not robot namespaces (robot_0, ...)')
    return {**{namespaced_topic(robot, topic): GRAPH_TOPICS[topic]
               for robot in robots for topic in own if topic != CLOCK_TOPIC},
            CLOCK_TOPIC: GRAPH_TOPICS[CLOCK_TOPIC]}
