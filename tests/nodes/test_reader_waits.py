"""A node that waits for named readers before it acts (``reader_matching.when_readers_matched``:
vision_node, tracker_node, controller_node) acts once they are matched, and says what it waits
for while it waits: a wait that does not end holds the robot's clock at 0, and the log is
where such a run is read."""

from __future__ import annotations

import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from std_msgs.msg import String

from omni_micro_common import reader_matching
from omni_micro_common.qos import DATA_QOS


class Said:
    """A logger that keeps what it is told to warn."""

    def __init__(self) -> None:
        self.warnings: list[str] = []

    def warning(self, message: str) -> None:
        self.warnings.append(message)


def test_a_wait_for_readers_says_what_it_waits_for_and_ends_once_they_match(context,
                                                                            monkeypatch):
    monkeypatch.setattr(reader_matching, 'WAIT_REPORT_S', 0.2)
    node = rclpy.create_node('camera_like', context=context)
    said = Said()
    monkeypatch.setattr(node, 'get_logger', lambda: said)
    publisher = node.create_publisher(String, '/captures_like', DATA_QOS)
    acted = []
    executor = SingleThreadedExecutor(context=context)
    executor.add_node(node)
    reader_node = None
    try:
        reader_matching.when_readers_matched(node, [(publisher, ['controller_like'])],
                                             lambda: acted.append(time.monotonic()))
        deadline = time.monotonic() + 0.7
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert not acted
        assert len(said.warnings) >= 2   # said again while it lasts
        assert said.warnings[0].startswith(
            "waiting 0 s for controller_like's reader of /captures_like (/captures_like: the "
            'graph shows 0 reader(s), its writer matched 0)'), said.warnings
        reader_node = rclpy.create_node('controller_like', context=context)
        reader_node.create_subscription(String, '/captures_like', lambda msg: None, DATA_QOS)
        deadline = time.monotonic() + 10.0
        while not acted and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert acted
        warned = len(said.warnings)
        for _ in range(10):   # the wait is over: nothing more said
            executor.spin_once(timeout_sec=0.05)
        assert len(said.warnings) == warned
    finally:
        executor.shutdown()
        if reader_node is not None:
            reader_node.destroy_node()
        node.destroy_node()

