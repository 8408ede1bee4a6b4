"""Bags compared message by message up to a run's outcome (the same-seed tests)."""

from __future__ import annotations

from pathlib import Path

from omni_micro_tools.bags import read_bag


def recorded_until(bag_path: Path, end_s: float) -> dict[str, list[bytes]]:
    """Every topic's messages (raw bytes, in order) stamped up to ``end_s``: after the outcome
    each recording runs on for as long as the shutdown takes."""
    bag = read_bag(bag_path)
    kept: dict[str, list[bytes]] = {}
    for topic in bag.raw:
        kept[topic] = []
        for raw, msg in zip(bag.raw[topic], bag.messages[topic], strict=True):
            stamp = msg.clock if topic == '/clock' else getattr(msg, 'header', None) and \
                msg.header.stamp
            if topic == '/markers':
                # Stamped by its markers; compared decoded: the serializer leaves the alignment
                # padding of a MarkerArray uninitialised, so equal arrays differ in those bytes.
                stamp = msg.markers[-1].header.stamp
                raw = repr(msg).encode()
            if stamp is None or stamp.sec + stamp.nanosec * 1e-9 <= end_s:
                kept[topic].append(raw)
    return kept
