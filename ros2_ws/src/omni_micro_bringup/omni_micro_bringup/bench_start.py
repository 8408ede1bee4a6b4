"""When a run on the bench may hand out its goal: once the controller has the real robot's state
and the tracker has a frame of every real camera; with several robots, once every robot's
controller has its driver's state and the cameras have named every robot.

Seeing a driver's publisher is not enough. Discovery runs each way at its own pace, so the
controller's reader may match the robot's driver, and the tracker's the camera's, a second or
more after the orchestrator saw them; a goal sent in between counts the controller's capture
timeout (3 x 1 s) from the goal while the first capture is still on its way (a run once ended
``lost`` at once, and one that reached had its first capture 1.9 s after the goal).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, Protocol

from diagnostic_msgs.msg import DiagnosticStatus

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.supervisor import Supervisor
from omni_micro_common.conventions import CAPTURE_AGE_KEY, FRAME_AGE_KEY, FRAME_RATE_KEY
from omni_micro_common.errors import LockstepError
from omni_micro_common.lockstep import ACK_TOPIC
from omni_micro_common.lockstep_groups import qualified_node_name
from omni_micro_common.lockstep_reporting import decode_ack_bytes
from omni_micro_common.qos import LOCKSTEP_QOS, latched
from omni_micro_common.topic_names import (
    JOINT_STATES_TOPIC,
    TRACKER_STATUS_TOPICS,
    namespaced_topic,
)

# What is still missing is named after this long (the drivers may take longer to start: the
# run waits on, up to its bound).
BENCH_NOTICE_S = 5.0
# How long a run on the bench waits for every robot's first state and the cameras' first frames
# (naming each robot), as for the drivers' topics.
BENCH_READY_S = 60.0
# The controller node whose wheel state the goal waits for.
CONTROLLER = 'controller_node'


class BenchWatcher(Protocol):
    """What the bench's wait needs of the orchestrator's node
    (:class:`omni_micro_bringup.orchestrator.Orchestrator`): its ROS node to listen with."""

    node: Any
    echo: Callable[[str], None] | None
    domain_id: int

    def spin_for(self, seconds: float) -> None: ...


def wait_for_bench(monitor: BenchWatcher, graph: Supervisor, robot: bool,
                   cameras: dict[str, str], timeout_s: float,
                   ages: bool = False) -> dict[str, str]:
    """Until the controller has had a wheel state (``robot``: the real robot's driver) and the
    tracker has handled a frame of each of ``cameras`` (camera -> the driver's image topic;
    with ``ages``, until it has said how old they come: a servo's corrections are timed by
    it); returns what the tracker says of each camera's latest frame.

    Raises
    ------
    RunFailed
        Naming what is still missing after ``timeout_s``, and where to look.
    """
    node, echo = monitor.node, monitor.echo
    said: dict[str, str] = {}
    with_state: set[int] = set()

    def tracker_status_of(camera: str) -> Callable[[DiagnosticStatus], None]:
        def on_status(msg: DiagnosticStatus) -> None:
            values = {item.key: item.value for item in msg.values}
            if not ages or CAPTURE_AGE_KEY in values:
                said[camera] = msg.message + _ages_said(values)
        return on_status

    subscriptions = [state_reports(node, {CONTROLLER: 0}, with_state)] if robot else []
    subscriptions += [node.create_subscription(DiagnosticStatus, TRACKER_STATUS_TOPICS[camera],
                                               tracker_status_of(camera), latched(1))
                      for camera in cameras]

    what = "frames' age" if ages else 'frame'

    def has_robot_state() -> bool:
        return not robot or bool(with_state)

    def missing() -> list[str]:
        return ([] if has_robot_state() else
                [f"the robot's first {JOINT_STATES_TOPIC} at {CONTROLLER}"]) + \
            [f"tracker_node's first {camera} {what} ({topic})"
             for camera, topic in cameras.items() if camera not in said]

    try:
        took = wait_until_present(monitor, graph, missing, lambda: not has_robot_state(),
                                  timeout_s)
    finally:
        for subscription in subscriptions:
            node.destroy_subscription(subscription)
    if echo:
        echo(f'[orchestration] the bench is ready after {took:.2f} s'
             + ''.join(f'; {camera}: {said[camera]}' for camera in cameras))
    return said


def wait_for_fleet_bench(monitor: BenchWatcher, graph: Supervisor, robots: list[str],
                         named: Callable[[], set[int]], timeout_s: float) -> None:
    """Until every robot's controller has had a wheel state of its driver and the cameras have
    named every robot (``named``: the robots whose captures have come), saying which are still
    missing after BENCH_NOTICE_S.

    Raises
    ------
    RunFailed
        Naming every robot still missing after ``timeout_s``, and where to look.
    """
    node, echo = monitor.node, monitor.echo
    with_state: set[int] = set()

    def missing() -> list[str]:
        return ([f"{robots[k]}'s first {namespaced_topic(robots[k], JOINT_STATES_TOPIC)}"
                 for k in range(len(robots)) if k not in with_state]
                + [f'a frame naming {robots[k]} (its code)' for k in range(len(robots))
                   if k not in named()])

    subscription = state_reports(node, {qualified_node_name(robot, CONTROLLER): k
                                        for k, robot in enumerate(robots)}, with_state)
    try:
        took = wait_until_present(monitor, graph, missing,
                                  lambda: len(with_state) < len(robots), timeout_s)
    finally:
        node.destroy_subscription(subscription)
    if echo:
        echo(f'[orchestration] the bench is ready after {took:.2f} s: every robot\'s driver '
             f'publishes, the cameras name {", ".join(robots)}')


def state_reports(node: Any, controllers: dict[str, int], with_state: set[int]) -> Any:
    """A subscription to /lockstep that adds to ``with_state`` each robot whose controller
    (``controllers``: its name on /lockstep -> the robot) has reported a wheel state handled."""
    def on_report(data: bytes) -> None:
        try:
            ack = decode_ack_bytes(data)
        except LockstepError:
            return   # not ours to judge: the nodes of the graph report well-formed
        if ack is not None and ack.node in controllers and (ack.processed_ns or 0) > 0:
            with_state.add(controllers[ack.node])

    return node.create_subscription(DiagnosticStatus, ACK_TOPIC, on_report, LOCKSTEP_QOS,
                                    raw=True)


def wait_until_present(monitor: BenchWatcher, graph: Supervisor,
                       missing: Callable[[], list[str]], robot_missing: Callable[[], bool],
                       timeout_s: float) -> float:
    """Until nothing is ``missing``: said when waiting starts and, with a hint (a robot's
    driver, while ``robot_missing``; else the camera's), after BENCH_NOTICE_S; returns how long
    it took.

    Raises
    ------
    RunFailed
        Naming what is still missing after ``timeout_s``.
    """
    echo = monitor.echo
    started = time.monotonic()
    noticed = False
    if missing() and echo:
        echo(f'[orchestration] waiting for {" and ".join(missing())} before the goal')
    while missing():
        graph.check_alive()
        waited = time.monotonic() - started
        hint = _hint(robot_missing(), monitor.domain_id)
        if waited > timeout_s:
            raise RunFailed(f'gave up waiting for {" and ".join(missing())} after '
                            f'{timeout_s:g} s: {hint}; logs in {graph.log_dir}')
        if waited > BENCH_NOTICE_S and not noticed and echo:
            noticed = True
            echo(f'[orchestration] still waiting for {" and ".join(missing())} after '
                 f'{BENCH_NOTICE_S:g} s: {hint}')
        monitor.spin_for(0.05)
    return time.monotonic() - started


def _ages_said(values: dict[str, str]) -> str:
    """', frames 79 ms old on arrival at 15.0 Hz' from a tracker status that says them."""
    try:
        return (f', frames {float(values[FRAME_AGE_KEY]) * 1e3:.0f} ms old on arrival at '
                f'{float(values[FRAME_RATE_KEY]):.1f} Hz')
    except (KeyError, ValueError):
        return ''


def _hint(robot_missing: bool, domain_id: int) -> str:
    where = f'in ROS_DOMAIN_ID {domain_id} with ROS_AUTOMATIC_DISCOVERY_RANGE LOCALHOST'
    if robot_missing:
        return (f"is the robot's driver publishing {JOINT_STATES_TOPIC} {where} (a driver that "
                'waits for its hardware says nothing until then)?')
    return f'is the camera driver streaming {where}, and has it a frame to give?'
