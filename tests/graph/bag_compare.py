"""Bags compared as files (the same-seed tests) and message by message (what a prefix is)."""

from __future__ import annotations

import hashlib
from pathlib import Path

from omni_micro_tools.bag_reading import read_bag


def bag_digest(bag_path: Path) -> str:
    """The sha256 of the bag's storage file and of its metadata.yaml, as one hex string."""
    (storage,) = [path for path in bag_path.iterdir() if path.suffix in ('.mcap', '.db3')]
    return '/'.join(hashlib.sha256(path.read_bytes()).hexdigest()
                    for path in (storage, bag_path / 'metadata.yaml'))


def stored_messages(bag_path: Path) -> list[tuple[str, int, bytes]]:
    """Every message of a bag as stored: topic, log time, serialized bytes, in stored order."""
    from mcap.reader import make_reader

    (storage,) = bag_path.glob('*.mcap')
    with open(storage, 'rb') as stream:
        return [(channel.topic, message.log_time, message.data)
                for _, channel, message in make_reader(stream).iter_messages(
                    log_time_order=False)]


def recorded_until(bag_path: Path, end_s: float) -> dict[str, list[bytes]]:
    """Every topic's messages (raw bytes, in order) stamped up to ``end_s``."""
    bag = read_bag(bag_path)
    kept: dict[str, list[bytes]] = {}
    for topic in bag.raw:
        kept[topic] = []
        for raw, msg in zip(bag.raw[topic], bag.messages[topic], strict=True):
            stamp = msg.clock if topic == '/clock' else getattr(msg, 'header', None) and \
                msg.header.stamp
            if topic == '/markers':
                stamp = msg.markers[-1].header.stamp
            if stamp is None or stamp.sec + stamp.nanosec * 1e-9 <= end_s:
                kept[topic].append(raw)
    return kept
