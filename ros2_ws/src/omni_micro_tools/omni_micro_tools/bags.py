"""rosbag2 bags of the graph through the `rosbags` library (no rosbag2 on this machine).

What is recorded, with which offered QoS, how a bag is opened for writing without clobbering
anything, how a bag whose recorder was killed is recovered, and how a bag is read back.
"""

from __future__ import annotations

import shutil
import sqlite3
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from omni_micro_tools.errors import BagDamagedError, BagPathError
from omni_micro_tools.topics import (
    GRAPH_TOPICS,
    STORAGE_NAMES,
    TopicSpec,
)

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
assert tuple(STORAGES) == STORAGE_NAMES
BAG_VERSION: Final = 9




def open_writer(path: Path, storage: str, topics: dict[str, TopicSpec]) -> tuple[Writer, dict]:
    if storage not in STORAGES:
        raise BagPathError(f'unknown storage {storage!r}: expected one of {sorted(STORAGES)}')
    writer = Writer(path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    writer.open()
    connections = {topic: writer.add_connection(topic, spec.msgtype, typestore=TYPESTORE,
                                                offered_qos_profiles=[spec.qos()])
                   for topic, spec in topics.items()}
    return writer, connections


def flush(writer: Writer) -> None:
    """Make everything written so far survive a SIGKILL of this process.

    rosbags keeps the current mcap chunk in memory (up to 1 MiB) and commits sqlite3 only on
    close; both are pushed to the file here. This reaches into the writer's storage object of
    the pinned rosbags 0.11.9 (requirements.lock); tests/bags/test_bags.py kills a recorder to
    keep it honest.
    """
    storage = writer.storage
    if storage is None:
        return
    if hasattr(storage, 'close_chunk'):
        # Private parts of rosbags' mcap writer (see above), which its stubs do not declare.
        if storage.chunk.msgs:  # type: ignore[attr-defined]
            storage.close_chunk()
        storage.bio.flush()  # type: ignore[attr-defined]
    elif hasattr(storage, 'conn'):
        storage.conn.commit()


def _recovered_topics(source: Path) -> Iterator[tuple[str, str, int, bytes]]:
    """(topic, msgtype, timestamp, data) of every complete message in a bag without metadata."""
    mcaps = sorted(source.glob('*.mcap'))
    databases = sorted(source.glob('*.db3'))
    if mcaps:
        from mcap.records import Channel, Message, Schema
        from mcap.stream_reader import StreamReader

        schemas: dict[int, str] = {}
        channels: dict[int, tuple[str, str]] = {}
        with open(mcaps[0], 'rb') as stream:
            reader = StreamReader(stream, skip_magic=False)
            try:
                for record in reader.records:
                    if isinstance(record, Schema):
                        schemas[record.id] = record.name
                    elif isinstance(record, Channel):
                        channels[record.id] = (record.topic, schemas[record.schema_id])
                    elif isinstance(record, Message):
                        topic, msgtype = channels[record.channel_id]
                        yield topic, msgtype, record.log_time, record.data
            except Exception:
                return
    elif databases:
        connection = sqlite3.connect(f'file:{databases[0]}?mode=ro', uri=True)
        try:
            topics = {row[0]: (row[1], row[2]) for row in
                      connection.execute('SELECT id, name, type FROM topics')}
            for topic_id, timestamp, data in connection.execute(
                    'SELECT topic_id, timestamp, data FROM messages ORDER BY id'):
                topic, msgtype = topics[topic_id]
                yield topic, msgtype, timestamp, bytes(data)
        finally:
            connection.close()
    else:
        raise BagPathError(f'{str(source)!r} holds no .mcap or .db3 file to recover')


def recover(source: Path, target: Path, storage: str = 'mcap') -> dict[str, int]:
    """Write every complete message of a bag whose recorder died into a new, readable bag.

    Returns the message count per topic.
    """
    if not source.is_dir():
        raise BagPathError(f'{str(source)!r} is not a bag folder')
    counts: dict[str, int] = {}
    writer = Writer(target, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    writer.open()
    connections = {}
    try:
        for topic, msgtype, timestamp, data in _recovered_topics(source):
            if topic not in connections:
                spec = GRAPH_TOPICS.get(topic, TopicSpec(msgtype, 1000))
                connections[topic] = writer.add_connection(
                    topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=[spec.qos()])
            writer.write(connections[topic], timestamp, data)
            counts[topic] = counts.get(topic, 0) + 1
    except BaseException:
        writer.close()
        shutil.rmtree(target, ignore_errors=True)
        raise
    writer.close()
    if not counts:
        shutil.rmtree(target, ignore_errors=True)
        raise BagDamagedError(f'no complete message could be recovered from {str(source)!r}')
    return counts


@dataclass
class BagMessages:
    """A bag read back: per topic, the receive timestamps (ns) and the decoded messages."""

    timestamps: dict[str, list[int]]
    messages: dict[str, list[Any]]   # decoded: rosbags builds their classes at run time
    raw: dict[str, list[bytes]]
    msgtypes: dict[str, str]


def check_readable_bag(path: Path) -> None:
    """Raises BagPathError saying why ``path`` is not a bag that can be read, and what to do."""
    if not path.exists():
        raise BagPathError(f'{str(path)!r} does not exist')
    if not path.is_dir():
        raise BagPathError(f'{str(path)!r} is a file: a rosbag2 bag is a folder with a '
                           f'metadata.yaml (give the folder)')
    if (path / 'metadata.yaml').is_file():
        return
    if any(child.suffix in ('.mcap', '.db3') for child in path.iterdir()):
        raise BagPathError(f'{str(path)!r} holds a bag file but no metadata.yaml: its recorder '
                           f'was killed; recover it with: omni-micro bag-recover {path}')
    raise BagPathError(f'{str(path)!r} is not a bag: no metadata.yaml and no .mcap or .db3 file')


def bag_topics(path: Path) -> list[str]:
    """The topics a bag holds, without reading its messages."""
    from rosbags.highlevel import AnyReader

    check_readable_bag(path)
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        return sorted({connection.topic for connection in reader.connections})


def read_bag(path: Path, topics: list[str] | None = None, decode: bool = True) -> BagMessages:
    from rosbags.highlevel import AnyReader

    check_readable_bag(path)
    result = BagMessages({}, {}, {}, {})
    with AnyReader([path], default_typestore=TYPESTORE) as reader:
        connections = [c for c in reader.connections if topics is None or c.topic in topics]
        for connection in connections:
            result.msgtypes[connection.topic] = connection.msgtype
            result.timestamps.setdefault(connection.topic, [])
            result.messages.setdefault(connection.topic, [])
            result.raw.setdefault(connection.topic, [])
        for connection, timestamp, rawdata in reader.messages(connections=connections):
            result.timestamps[connection.topic].append(timestamp)
            result.raw[connection.topic].append(bytes(rawdata))
            if decode:
                result.messages[connection.topic].append(
                    reader.deserialize(rawdata, connection.msgtype))
    return result
