"""rosbag2 bags of the graph through the `rosbags` library (no rosbag2 on this machine).

What is recorded, with which offered QoS, how a bag is opened for writing without clobbering
anything, how a recorded bag is finished in the order of simulated time
(:mod:`omni_micro_tools.bag_order`), and how a bag whose recorder was killed is recovered.
Reading a bag back is :mod:`omni_micro_tools.bag_reading`'s.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import struct
import zlib
from pathlib import Path
from typing import Any, Final

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from omni_micro_tools.bag_order import RECOVERY_WINDOW_S, Ordered, in_bag_order
from omni_micro_tools.bag_salvage import finished_by_its_recorder, reader_of, stored_file
from omni_micro_tools.errors import BagDamagedError, BagPathError
from omni_micro_tools.salvage_report import Recovery
from omni_micro_tools.topics import GRAPH_TOPICS, STORAGE_NAMES, TopicSpec

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}
assert tuple(STORAGES) == STORAGE_NAMES
BAG_VERSION: Final = 9
# A finished bag's chunks span this much of its time at most (rosbags closes one at 1 MiB, half
# of a Fig. 11 run): a damaged chunk then costs at most this much of the run.
CHUNK_SPAN_NS = 500_000_000


def open_writer(path: Path, storage: str, topics: dict[str, TopicSpec]) -> tuple[Writer, dict]:
    if storage not in STORAGES:
        raise BagPathError(f'unknown storage {storage!r}: expected one of {sorted(STORAGES)}')
    writer = Writer(path, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    writer.open()
    if hasattr(writer.storage, 'close_chunk'):
        _write_chunk_crcs(writer.storage)
    connections = {topic: writer.add_connection(topic, spec.msgtype, typestore=TYPESTORE,
                                                offered_qos_profiles=[spec.qos()])
                   for topic, spec in topics.items()}
    return writer, connections


def check_bag_output(path: Path, force: bool) -> None:
    """Refuse to overwrite, unless ``force`` and the path is a bag (never an arbitrary folder)."""
    if not path.exists():
        # Made here, as demo does: a newcomer's `--record out/bags/mine` should just work.
        path.parent.mkdir(parents=True, exist_ok=True)
        return
    if not force:
        raise BagPathError(f'{str(path)!r} exists already; give --force to replace it')
    looks_like_bag = path.is_dir() and all(
        child.name == 'metadata.yaml' or child.suffix in ('.mcap', '.db3')
        for child in path.iterdir())
    if not looks_like_bag:
        raise BagPathError(f'{str(path)!r} exists and is not a bag; not replacing it even with '
                         f'--force')
    shutil.rmtree(path)


# In an mcap Chunk record: the opcode (1 byte), the record's length (8), the start and end
# times and the uncompressed size (24), then the CRC32 of the uncompressed chunk (4).
_CHUNK_CRC_OFFSET = 1 + 8 + 24


def _write_chunk_crcs(storage: Any) -> None:
    """Have every chunk carry the CRC32 of its data, as rosbag2's mcap writer does by default:
    rosbags writes 0 (none), and a bag with bytes flipped in a chunk then read back wrong
    numbers without a word. The pinned rosbags 0.11.9 (requirements.lock) writes a chunk whole
    in ``close_chunk`` and indexes it in ``chunks``; the CRC is set in its place after."""
    close_chunk = storage.close_chunk

    def close_chunk_with_crc() -> None:
        crc = zlib.crc32(storage.chunk.bio.getbuffer())
        close_chunk()
        start = struct.unpack_from('<Q', storage.chunks[-1].getbuffer(), 16)[0]
        end = storage.bio.tell()
        storage.bio.seek(start + _CHUNK_CRC_OFFSET)
        storage.bio.write(struct.pack('<I', crc))
        storage.bio.seek(end)

    storage.close_chunk = close_chunk_with_crc


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


def _write_in_order(source: Path, target: Path, storage: str, end: str,
                    topics: dict[str, TopicSpec] | None) -> tuple[Ordered, Recovery]:
    """Write the messages of the bag folder ``source`` into a new bag at ``target`` in bag
    order (omni_micro_tools.bag_order); with ``topics``, every one of them gets its connection
    in that order, as the recorder opened them, whether or not it has messages. Nothing is left
    at ``target`` if this raises."""
    report = Recovery({})
    messages, ordered = in_bag_order(reader_of(stored_file(source), report), TYPESTORE, end)
    writer = Writer(target, version=BAG_VERSION, storage_plugin=STORAGES[storage])
    writer.open()
    try:
        if hasattr(writer.storage, 'close_chunk'):
            _write_chunk_crcs(writer.storage)
        connections = {} if topics is None else {
            topic: writer.add_connection(topic, spec.msgtype, typestore=TYPESTORE,
                                         offered_qos_profiles=[spec.qos()])
            for topic, spec in topics.items()}
        chunk_from = None
        for topic, msgtype, timestamp, data in messages:
            if topic not in connections:
                spec = GRAPH_TOPICS.get(topic, TopicSpec(msgtype, 1000))
                connections[topic] = writer.add_connection(
                    topic, msgtype, typestore=TYPESTORE, offered_qos_profiles=[spec.qos()])
            if chunk_from is None or timestamp - chunk_from >= CHUNK_SPAN_NS:
                if chunk_from is not None:
                    flush(writer)
                chunk_from = timestamp
            writer.write(connections[topic], timestamp, data)
    except BaseException:
        # A full disk fails the close too, and the storage may be closed already.
        with contextlib.suppress(OSError, ValueError):
            writer.close()
        shutil.rmtree(target, ignore_errors=True)
        raise
    try:
        writer.close()
    except OSError:
        shutil.rmtree(target, ignore_errors=True)
        raise
    report.counts = dict(ordered.counts)
    report.dropped += ordered.undecodable
    report.undecodable = ordered.undecodable
    return ordered, report


def finish_in_order(bag: Path, storage: str, topics: dict[str, TopicSpec],
                    whole: bool = False) -> Ordered:
    """Rewrite a closed bag the recorder wrote in arrival order as a finished bag: in the order
    of simulated time, ending BAG_TAIL_S after the run's last outcome (``whole``: at its last
    message). The bag is replaced only once the new one is complete; until then it stays as it
    was (a failure raises OSError and leaves it so)."""
    work = bag.parent / f'.{bag.name}.ordering'
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    try:
        ordered, _ = _write_in_order(bag, work / bag.name, storage,
                                     'all' if whole else 'outcome', topics)
        # Without metadata.yaml for a moment: a kill here leaves a bag that bag-recover reads.
        (bag / 'metadata.yaml').unlink()
        # The metadata last: with it, the bag is whole again.
        for finished in sorted((work / bag.name).iterdir(),
                               key=lambda path: path.name == 'metadata.yaml'):
            os.replace(finished, bag / finished.name)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return ordered


def recover(source: Path, target: Path, storage: str = 'mcap',
            keep_unsure_tail: bool = False) -> Recovery:
    """Write every intact message of a bag whose recorder died, or whose file was cut short or
    damaged, into a new readable bag, in bag order; a message that does not decode as its type
    is dropped (damaged bytes that the chunk's CRC did not catch), and so are the messages of
    the last RECOVERY_WINDOW_S of simulated time of a file its recorder did not finish (no
    footer), which may have been incomplete when the recorder died: what is kept is a prefix of
    the bag the run would have recorded (``keep_unsure_tail``: those are kept too, and it may
    not be). A finished file damaged later (a bad disk, a copy) keeps its tail.

    Raises
    ------
    BagPathError
        ``source`` is not a folder holding an .mcap or .db3 file.
    BagDamagedError
        Not one message could be recovered.
    """
    if not source.is_dir():
        raise BagPathError(f'{str(source)!r} is not a bag folder')
    try:
        file = stored_file(source)
    except BagPathError:
        raise BagPathError(f'{str(source)!r} holds no .mcap or .db3 file to recover') from None
    sure = keep_unsure_tail or finished_by_its_recorder(file)
    ordered, report = _write_in_order(source, target, storage, 'all' if sure else 'recovered',
                                      None)
    report.unsure_tail = ordered.after_end
    if not report.counts:
        shutil.rmtree(target, ignore_errors=True)
        if report.unsure_tail:
            raise BagDamagedError(
                f'all {report.unsure_tail} messages of {str(source)!r} are within its last '
                f'{RECOVERY_WINDOW_S:g} s of simulated time, which may be incomplete: '
                'bag-recover --keep-unsure-tail keeps them')
        raise BagDamagedError(f'no complete message could be recovered from {str(source)!r}')
    return report


