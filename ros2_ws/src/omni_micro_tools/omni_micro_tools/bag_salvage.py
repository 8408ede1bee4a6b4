"""Reading what a damaged bag still holds: every message of its intact chunks, footer or not, and
a count of what could not be read (:func:`omni_micro_tools.bags.recover` writes it into a new
bag). The mcap file's walk is :mod:`omni_micro_tools.mcap_salvage`'s, the report
:mod:`omni_micro_tools.salvage_report`'s."""

from __future__ import annotations

import os
import sqlite3
from collections.abc import Callable, Iterator
from pathlib import Path

from mcap.opcode import Opcode

from omni_micro_tools.bag_order import Stored
from omni_micro_tools.errors import BagPathError
from omni_micro_tools.mcap_salvage import FOOTER_SIZE, MAGIC, mcap_messages
from omni_micro_tools.salvage_report import Recovery


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
        return mcap_messages(file, report if readings == 1 else Recovery({}))
    return read
