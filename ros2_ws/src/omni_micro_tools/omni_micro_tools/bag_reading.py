"""A recorded bag read back through `rosbags`; whatever is wrong with it is said in one line
that names the bag and what to do (bag-recover)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from omni_micro_common.errors import OmniMicroError
from omni_micro_tools.bags import TYPESTORE
from omni_micro_tools.errors import BagDamagedError, BagPathError
from omni_micro_tools.mcap_salvage import MCAP_DAMAGE


@dataclass
class BagMessages:
    """A bag read back: per topic, the receive timestamps (ns) and the decoded messages."""

    timestamps: dict[str, list[int]]
    messages: dict[str, list[Any]]   # decoded: rosbags builds their classes at run time
    raw: dict[str, list[bytes]]
    msgtypes: dict[str, str]


def check_readable_bag(path: Path) -> None:
    """Raises BagPathError saying why ``path`` is not a bag that can be read, and what to do."""
    try:
        _check_readable_bag(path)
    except OSError as error:   # a name too long for the file system, a folder not readable
        raise BagPathError(f'{str(path)!r} cannot be read: {error.strerror or error}') from None


def _check_readable_bag(path: Path) -> None:
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


@contextlib.contextmanager
def reading(path: Path) -> Iterator[Any]:
    """An AnyReader over the bag at ``path``, whatever is wrong with it said in one line that
    names the bag (BagPathError: not a bag; BagDamagedError: a bag that cannot be read whole)."""
    import yaml
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.rosbag2 import ReaderError

    check_readable_bag(path)
    try:
        with AnyReader([path], default_typestore=TYPESTORE) as reader:
            yield reader
    except OmniMicroError:
        raise   # the caller's own, said already
    except (AnyReaderError, ReaderError, *MCAP_DAMAGE, yaml.YAMLError, OSError) as error:
        reason = (str(error).strip().splitlines() or [type(error).__name__])[0].rstrip('.')
        if isinstance(error, yaml.YAMLError | UnicodeDecodeError):
            raise BagDamagedError(f'bag {str(path)!r}: its metadata.yaml is not readable YAML '
                                  f'({reason})') from None
        hint = ''
        if 'checksum' in reason.lower():
            reason += _damaged_chunks_said(path)
        if 'magic' in reason.lower() or 'end of file' in reason.lower() \
                or isinstance(error, EOFError):
            hint = ('; the file looks cut short (a killed recorder, a copy cut off): '
                    f'omni-micro bag-recover {path} keeps every intact message')
        else:
            hint = (f'; omni-micro bag-recover {path} keeps every message that still decodes')
        raise BagDamagedError(f'bag {str(path)!r} is damaged: {reason}{hint}') from None


def _damaged_chunks_said(path: Path) -> str:
    """Which chunks of a bag's mcap files fail their CRC, for a message: ' in chunk 3 of 12
    (messages from 4.200 to 5.400 s)'."""
    from mcap.records import Chunk
    from mcap.stream_reader import StreamReader, breakup_chunk

    said = []
    for file in sorted(path.glob('*.mcap')):
        with contextlib.suppress(*MCAP_DAMAGE, OSError), open(file, 'rb') as stream:
            chunks = [record for record in StreamReader(stream, emit_chunks=True).records
                      if isinstance(record, Chunk)]
            for number, chunk in enumerate(chunks, 1):
                try:
                    breakup_chunk(chunk, validate_crc=True)
                except MCAP_DAMAGE:
                    said.append(f'chunk {number} of {len(chunks)} of {file.name} (messages from '
                                f'{chunk.message_start_time * 1e-9:.3f} to '
                                f'{chunk.message_end_time * 1e-9:.3f} s)')
    return f' in {", ".join(said)}' if said else ''


def bag_topics(path: Path) -> list[str]:
    """The topics a bag holds, without reading its messages."""
    with reading(path) as reader:
        return sorted({connection.topic for connection in reader.connections})


def bag_message_counts(path: Path) -> dict[str, int]:
    """How many messages a bag holds of each topic, as its index says (without reading them)."""
    counts: dict[str, int] = {}
    with reading(path) as reader:
        for connection in reader.connections:
            counts[connection.topic] = counts.get(connection.topic, 0) + connection.msgcount
    return counts


def read_bag(path: Path, topics: list[str] | None = None, decode: bool = True) -> BagMessages:
    """A bag's messages (all, or those of ``topics``), each decoded unless ``decode`` is False.

    Raises
    ------
    BagPathError
        ``path`` is not a bag (missing, a file, no metadata.yaml: it names bag-recover then).
    BagDamagedError
        The bag cannot be read whole; the message says why and how to recover it.
    """
    result = BagMessages({}, {}, {}, {})
    with reading(path) as reader:
        connections = [c for c in reader.connections if topics is None or c.topic in topics]
        for connection in connections:
            result.msgtypes[connection.topic] = connection.msgtype
            result.timestamps.setdefault(connection.topic, [])
            result.messages.setdefault(connection.topic, [])
            result.raw.setdefault(connection.topic, [])
        if not connections:
            return result   # none of those topics: rosbags would read every topic instead
        for connection, timestamp, rawdata in reader.messages(connections=connections):
            result.timestamps[connection.topic].append(timestamp)
            result.raw[connection.topic].append(bytes(rawdata))
            if decode:
                result.messages[connection.topic].append(
                    reader.deserialize(rawdata, connection.msgtype))
    return result
