"""The live view: a client that connects the moment the port opens is offered every channel at
once; for a fleet the viewer serves every robot's topics under its namespace and the one
/clock, a Foxglove client is offered each with its schema, and the fleet's graph starts it with
its robots."""

from __future__ import annotations

import asyncio
import json
import math
import threading
import time

import pytest
import websockets
from adapter_helpers import overrides
from foxglove_client import free_port
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from websockets.typing import Subprotocol

from omni_micro_bringup.graph_options import FleetRun, GraphOptions
from omni_micro_bringup.node_overrides import wired_specs
from omni_micro_bringup.node_spec import process_argv
from omni_micro_common.errors import ParameterError
from omni_micro_control.fleet_plan import plan_fleet
from omni_micro_sim.parameters import RobotParameters
from omni_micro_tools.viewer_node import Viewer


async def advertised(url: str) -> dict[str, str]:
    """Each channel a Foxglove client is offered, with its schema's name."""
    async with websockets.connect(url, subprotocols=[Subprotocol('foxglove.sdk.v1')]) as client:
        while True:
            message = json.loads(await asyncio.wait_for(client.recv(), timeout=10.0))
            if message['op'] == 'advertise':
                return {channel['topic']: channel['schemaName']
                        for channel in message['channels']}


def test_a_client_connecting_as_the_port_opens_is_offered_every_channel_at_once(context):
    """Once listening, the viewer has every channel: a client offered a channel while they were
    still being made had its subscription to it refused (no /odom reached a test's client)."""
    port = free_port()
    first_offer: list[dict[str, str]] = []

    def connect_as_soon_as_it_listens() -> None:
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            try:
                first_offer.append(asyncio.run(advertised(f'ws://127.0.0.1:{port}')))
                return
            except OSError:
                time.sleep(0.001)
    client = threading.Thread(target=connect_as_soon_as_it_listens, daemon=True)
    client.start()
    viewer = Viewer(context=context, parameter_overrides=overrides(port=port))
    try:
        client.join(timeout=30.0)
        assert first_offer and set(first_offer[0]) == set(viewer.channels)
    finally:
        viewer.stop()
        viewer.destroy_node()


def test_each_robot_s_topics_are_served_under_its_namespace_with_one_clock(context):
    viewer = Viewer(context=context, parameter_overrides=overrides(
        port=0, robots=['robot_0', 'robot_1']))
    try:
        topics = set(viewer.channels)
        assert '/clock' in topics and not {'/odom', '/markers', '/robot_0/clock'} & topics
        assert {'/robot_0/markers', '/robot_1/markers', '/robot_1/odom',
                '/robot_0/controller/status', '/robot_1/camera/micro/pose'} <= topics
        offered = asyncio.run(advertised(f'ws://127.0.0.1:{viewer.server.port}'))
        assert set(offered) == topics
        assert offered['/robot_1/markers'] == 'visualization_msgs/msg/MarkerArray'
        odometry = Odometry()
        odometry.header.frame_id = 'robot_1/odom'
        viewer._forwarder('/robot_1/odom')(serialize_message(odometry))
        assert viewer.forwarded['/robot_1/odom'] == 1 and viewer.forwarded['/robot_0/odom'] == 0
    finally:
        viewer.stop()
        viewer.destroy_node()


def test_a_robot_namespace_that_is_not_one_name_is_refused(context):
    with pytest.raises(ParameterError, match=r"robots: \['robot 1'\] are not robot namespaces"):
        Viewer(context=context, parameter_overrides=overrides(port=0, robots=['robot 1']))


def test_the_fleet_s_graph_starts_the_view_with_its_robots_and_without_it_none(tmp_path):
    def specs(view):
        plan = plan_fleet([(0.0, 0.0), (0.05, 0.0), (0.1, 0.02)], [[], [], []])
        return wired_specs(GraphOptions(seed=1, real_time_factor=math.inf, markers=True,
                                        view=view, fleet=FleetRun(plan, [RobotParameters()] * 3,
                                                                  ['paper'] * 3)), tmp_path)
    (viewer,) = [spec for spec in specs(('127.0.0.1', 8799)) if spec.executable == 'viewer']
    arguments = ' '.join(process_argv(viewer))
    for expected in ("host:=127.0.0.1", 'port:=8799', 'markers:=true',
                     'robots:=[robot_0,robot_1,robot_2]'):
        assert expected in arguments, arguments
    assert not [spec for spec in specs(None) if spec.executable == 'viewer']
