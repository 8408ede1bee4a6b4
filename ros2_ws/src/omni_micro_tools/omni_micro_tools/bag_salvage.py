"""Reading what a damaged bag still holds: every message of its intact chunks, footer or not, and
a count of what could not be read (:func:`omni_micro_tools.bags.recover` writes it into a new
bag)."""

from __future__ import annotations

import sqlite3
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mcap.exceptions import McapError

from omni_micro_tools.bag_order import Stored
from omni_micro_tools.errors import BagPathError

# A damaged file can announce records of any length; nothing the recorder writes is this big.
RECORD_SIZE_LIMIT = 1 << 30
# What reading a damaged mcap file raises: the library's own errors, and what its parsers hit
# on bytes that are not what they should be.
MCAP_DAMAGE = (McapError, struct.error, ValueError, EOFError, UnicodeDecodeError, KeyError)


@dataclass
class Recovery:
    """What ``recover`` kept and what it could not."""

    counts: dict[str, int]          # messages kept, per topic
    dropped: int = 0                # messages of damaged chunks, or that did not decode
    damaged_chunks: int = 0
    cut_short: bool = False         # the file ends inside a record (a kill, a copy cut short)
    unsure_tail: int = 0            # whole messages of the last RECOVERY_WINDOW_S, left out

    @property
    def kept(self) -> int:
        return sum(self.counts.values())


def _mcap_messages(path: Path, report: Recovery) -> Iterator[tuple[str, str, int, bytes]]:
    """Every message of every intact chunk of an mcap file, footer or not: a chunk that does
    not parse is skipped (its messages counted from the indexes after it), and reading stops
    where the file's framing does."""
    from mcap.records import Channel, Chunk, Message, MessageIndex, Schema
    from mcap.stream_reader import StreamReader, breakup_chunk

    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, str]] = {}

    def from_records(records: list[Any]) -> list[tuple[str, str, int, bytes]]:
        messages = []
        for record in records:
            if isinstance(record, Schema):
                schemas[record.id] = record.name
            elif isinstance(record, Channel):
                channels[record.id] = (record.topic, schemas[record.schema_id])
            elif isinstance(record, Message):
                topic, msgtype = channels[record.channel_id]
                messages.append((topic, msgtype, record.log_time, record.data))
        return messages

    # A chunk's messages wait for the indexes that follow it: a record whose length was damaged
    # can swallow the records after it, and only the indexes tell how many there were.
    pending: list[tuple[str, str, int, bytes]] = []
    indexed = 0

    def settle() -> list[tuple[str, str, int, bytes]]:
        nonlocal pending, indexed
        if indexed > len(pending):
            report.damaged_chunks += 1
            report.dropped += indexed - len(pending)
        done, pending, indexed = pending, [], 0
        return done

    with open(path, 'rb') as stream:
        reader = StreamReader(stream, skip_magic=False, emit_chunks=True,
                              record_size_limit=RECORD_SIZE_LIMIT)
        try:
            for record in reader.records:
                if isinstance(record, MessageIndex):
                    indexed += len(record.records)
                    continue
                yield from settle()
                if isinstance(record, Chunk):
                    try:
                        pending = from_records(breakup_chunk(record, validate_crc=True))
                    except MCAP_DAMAGE:
                        pending = []   # its indexes, next, say how many it held
                else:
                    yield from from_records([record])
        except MCAP_DAMAGE:
            report.cut_short = True
        yield from settle()


def _sqlite_messages(path: Path) -> Iterator[tuple[str, str, int, bytes]]:
    connection = sqlite3.connect(f'file:{path}?mode=ro', uri=True)
    try:
        topics = {row[0]: (row[1], row[2]) for row in
                  connection.execute('SELECT id, name, type FROM topics')}
        for topic_id, timestamp, data in connection.execute(
                'SELECT topic_id, timestamp, data FROM messages ORDER BY id'):
            topic, msgtype = topics[topic_id]
            yield topic, msgtype, timestamp, bytes(data)
    finally:
        connection.close()


def stored_file(folder: Path) -> Path:
    mcaps, databases = sorted(folder.glob('*.mcap')), sorted(folder.glob('*.db3'))
    if not mcaps and not databases:
        raise BagPathError(f'{str(folder)!r} holds no .mcap or .db3 file')
    return mcaps[0] if mcaps else databases[0]


def reader_of(file: Path, report: Recovery) -> Callable[[], Iterator[Stored]]:
    """Reads ``file``'s messages in stored order; the first reading counts what is damaged."""
    readings = 0

    def read() -> Iterator[Stored]:
        nonlocal readings
        readings += 1
        if file.suffix == '.db3':
            return _sqlite_messages(file)
        return _mcap_messages(file, report if readings == 1 else Recovery({}))
    return read
