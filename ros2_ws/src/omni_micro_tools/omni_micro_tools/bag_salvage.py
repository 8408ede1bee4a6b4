"""Reading what a damaged bag still holds: every message of its intact chunks, footer or not, and
a count of what could not be read (:func:`omni_micro_tools.bags.recover` writes it into a new
bag). The mcap file's walk is :mod:`omni_micro_tools.mcap_salvage`'s."""

from __future__ import annotations

import os
import sqlite3
import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.opcode import Opcode

from omni_micro_tools.bag_order import Stored
from omni_micro_tools.errors import BagPathError

# The mcap specification's magic, with which a file starts and ends, and its footer record's
# size (opcode, length, two offsets and a CRC).
MAGIC = b'\x89MCAP0\r\n'
FOOTER_SIZE = 1 + 8 + 8 + 8 + 4
# A damaged file can announce records of any length; nothing the recorder writes is this big.
RECORD_SIZE_LIMIT = 1 << 30
# What reading a damaged mcap file raises: the library's own errors, and what its parsers hit
# on bytes that are not what they should be.
MCAP_DAMAGE = (McapError, struct.error, ValueError, EOFError, UnicodeDecodeError, KeyError)


@dataclass(frozen=True)
class DroppedStretch:
    """Messages a damaged stretch of the file took with it: how many (None: the file no longer
    says) and between which log times (ns; None: the bag's start, or its end)."""

    count: int | None
    from_ns: int | None
    to_ns: int | None

    def said(self) -> str:
        """'12 between 4.200 and 5.380 s', as bag-recover prints it."""
        def when(ns: int | None, otherwise: str) -> str:
            return otherwise if ns is None else f'{ns * 1e-9:.3f} s'
        count = 'an unknown number' if self.count is None else str(self.count)
        return (f'{count} between {when(self.from_ns, "the start")} and '
                f'{when(self.to_ns, "the end")}')


@dataclass
class Recovery:
    """What ``recover`` kept and what it could not."""

    counts: dict[str, int]          # messages kept, per topic
    dropped: int = 0                # messages of damaged chunks, or that did not decode
    undecodable: int = 0            # of those, read whole but not decodable as their type
    damaged_chunks: int = 0         # damaged stretches of the file (a chunk, or more)
    cut_short: bool = False         # the file ends inside a record (a kill, a copy cut short)
    unsure_tail: int = 0            # whole messages of the last RECOVERY_WINDOW_S, left out
    stretches: list[DroppedStretch] = field(default_factory=list)   # where the damage lies

    @property
    def kept(self) -> int:
        return sum(self.counts.values())


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


def finished_by_its_recorder(file: Path) -> bool:
    """Whether the recorder finished ``file``: an mcap file with its footer and closing magic
    (whatever happened to it since); a sqlite3 database with its metadata.yaml beside it."""
    if file.suffix == '.db3':
        return (file.parent / 'metadata.yaml').is_file()
    with open(file, 'rb') as stream:
        size = stream.seek(0, os.SEEK_END)
        if size < 2 * len(MAGIC) + FOOTER_SIZE:
            return False
        stream.seek(size - len(MAGIC) - FOOTER_SIZE)
        tail = stream.read()
    return tail[0] == Opcode.FOOTER and tail.endswith(MAGIC)


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
        # Here: the walk reports in this module's terms.
        from omni_micro_tools.mcap_salvage import mcap_messages

        return mcap_messages(file, report if readings == 1 else Recovery({}))
    return read
