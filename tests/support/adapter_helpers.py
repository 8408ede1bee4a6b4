"""What the node adapter tests share: parameter overrides by keyword, and the check that a node
reads its input only once the readers that must not miss its output are matched."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any, cast

import numpy as np
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image


def overrides(**values: object) -> list[Parameter]:
    return [Parameter(name.replace('__', '.'), value=value) for name, value in values.items()]


def assert_reads_input_only_once_matched(context, node: Node, reader_name: str,
                                            make_readers: Callable[[Node], object],
                                            input_topic: str = '/odom',
                                            first_said_on: str | None = None) -> None:
    """``node`` has no reader of ``input_topic`` (so the robot's clock would not start) until
    the readers that ``make_readers`` gives a node named ``reader_name`` are matched; nor, with
    ``first_said_on``, has it published on that topic (its publication counter says)."""
    reader = rclpy.create_node(reader_name, context=context)
    executor = SingleThreadedExecutor(context=context)
    try:
        def reads_input() -> bool:
            return any(sub.topic_name == input_topic for sub in node.subscriptions)

        def said() -> int:
            assert first_said_on is not None
            # Each of the project's nodes counts what it publishes (PublicationCounter).
            return cast(Any, node).publication_counter.counts[first_said_on]
        executor.add_node(node)
        executor.spin_once(timeout_sec=0.2)
        assert not reads_input()
        if first_said_on:
            assert said() == 0
        make_readers(reader)
        deadline = time.monotonic() + 10.0
        while not reads_input() and time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
        assert reads_input()
        if first_said_on:
            assert said() == 1
    finally:
        executor.shutdown()
        reader.destroy_node()
        node.destroy_node()


def frame(pixels: np.ndarray, stamp_ns: int) -> tuple[Image, CameraInfo]:
    """A mono8 frame of ``pixels`` stamped ``stamp_ns``, and its CameraInfo, as a driver sends
    them."""
    image = Image(height=pixels.shape[0], width=pixels.shape[1], encoding='mono8',
                  is_bigendian=0, step=pixels.shape[1], data=pixels.tobytes())
    image.header.stamp.sec, image.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    info = CameraInfo(height=pixels.shape[0], width=pixels.shape[1])
    info.header = image.header
    return image, info
