"""An mcap file walked record by record, trusting nothing (:class:`_McapSalvage`): what
``omni-micro bag-recover`` keeps of a damaged or cut file, and what it says was lost
(:mod:`omni_micro_tools.salvage_report`)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import mmap
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from mcap.exceptions import McapError
from mcap.opcode import Opcode

from omni_micro_tools.bag_order import Stored
from omni_micro_tools.salvage_report import DroppedStretch, Recovery

# The mcap specification's magic, with which a file starts and ends, and its footer record's
# size (opcode, length, two offsets and a CRC).
MAGIC = b'\x89MCAP0\r\n'
FOOTER_SIZE = 1 + 8 + 8 + 8 + 4
# A damaged file can announce records of any length; nothing the recorder writes is this big.
RECORD_SIZE_LIMIT = 1 << 30
# What reading a damaged mcap file raises: the library's own errors, and what its parsers hit
# on bytes that are not what they should be.
MCAP_DAMAGE = (McapError, struct.error, ValueError, EOFError, UnicodeDecodeError, KeyError)

_LAST_OPCODE = max(Opcode)
# The smallest message record: opcode, length, channel, sequence, log and publish time.
_SMALLEST_MESSAGE = 1 + 8 + 2 + 4 + 8 + 8


def _u64(data: memoryview | bytes, at: int) -> int:
    return int.from_bytes(data[at:at + 8], 'little')


def _u32(data: memoryview | bytes, at: int) -> int:
    return int.from_bytes(data[at:at + 4], 'little')


@dataclass
class _Stretch:
    """A damaged stretch being walked through: the last message read before it, how many
    messages it held (None: unknown) and the times its surviving headers and indexes name."""

    after_ns: int | None
    count: int | None = 0
    times: list[int] = field(default_factory=list)


# What the other records of a data section hold, field by field (the mcap specification): 'h',
# 'i', 'q' fixed integers of 2, 4 and 8 bytes, 's' a string and 'b' bytes (each after its u32
# length), 'm' a map (after its u32 length in bytes). A record must be exactly that long.
_SHAPES = {Opcode.HEADER: 'ss', Opcode.SCHEMA: 'hssb', Opcode.CHANNEL: 'hhssm',
           Opcode.METADATA: 'sm', Opcode.FOOTER: 'qqi'}
_FIXED = {'h': 2, 'i': 4, 'q': 8}


def _fills(body: memoryview, shape: str) -> bool:
    """Whether ``body`` is exactly the fields of ``shape`` (see _SHAPES)."""
    at = 0
    for field_kind in shape:
        if field_kind in _FIXED:
            at += _FIXED[field_kind]
        else:
            if at + 4 > len(body):
                return False
            at += 4 + _u32(body, at)
        if at > len(body):
            return False
    return at == len(body)


def _chunk_records(body: memoryview) -> tuple[bytes, bool] | None:
    """A chunk's uncompressed records and whether they agree with its CRC (a CRC of 0 says
    none), if its header agrees with its length (None: it does not, or they are compressed,
    which nothing here writes)."""
    if len(body) < 40:
        return None
    size, crc, name_length = _u64(body, 16), _u32(body, 24), _u32(body, 28)
    if 40 + name_length > len(body):
        return None
    compression = bytes(body[32:32 + name_length])
    if compression or 40 + name_length + _u64(body, 32 + name_length) != len(body):
        return None
    records = body[40 + name_length:].tobytes()
    if size != len(records):
        return None
    return records, not crc or zlib.crc32(records) == crc


class _McapSalvage:
    """A walk through an mcap file record by record that trusts nothing: each record's length is
    checked against what its body says, each chunk against its CRC. Where the framing breaks (a
    length overwritten, a stretch of bad sectors) the walk finds the next record that checks
    out and goes on from there, so the intact chunks after a damaged one are kept too. What a
    damaged stretch held is counted from the message indexes that follow each chunk, or, for a
    finished file, from its summary's statistics."""

    def __init__(self, data: memoryview, report: Recovery) -> None:
        self.data = data
        self.report = report
        self.schemas: dict[int, str] = {}
        self.channels: dict[int, tuple[str, str]] = {}
        self.total: int | None = None     # the summary's message count, if the file has one
        self.seen = 0                      # messages read out of intact records
        self.last_ns: int | None = None    # the log time of the last message read
        # The chunk read last, whose indexes (after it) say how many messages it held; for a
        # damaged one, the times its header names.
        self._pending: list[Stored] = []
        self._damaged: tuple[int, int] | None = None
        self._indexed: list[int] = []
        self._orphans = 0   # messages of the chunk read last whose channel is unknown
        self._stretch: _Stretch | None = None

    # -- the walk ----------------------------------------------------------------------------
    def messages(self) -> Iterator[Stored]:
        self._read_summary()
        data = self.data
        at = len(MAGIC) if bytes(data[:len(MAGIC)]) == MAGIC else self._resync(0)
        complete = False
        while at is not None and at + 9 <= len(data):
            opcode, end = data[at], at + 9 + _u64(data, at + 1)
            body = self._checked(at)
            if body is None and opcode == Opcode.CHUNK:
                # Its length overwritten, the rest of its header whole: the end the header
                # implies, if a record checks out there.
                header_end = self._chunk_end_by_header(at)
                if header_end is not None:
                    end, body = header_end, data[at + 9:header_end]
            if body is None:
                yield from self._settle()   # the chunk before, by the indexes read so far
                at = self._resync(at + 1)
                if at is not None:
                    self._lose(None)   # the framing was lost: how much with it, unknown
                continue   # (none found: the file ends mid-record, cut short)
            if opcode == Opcode.MESSAGE_INDEX:
                self._indexed += [_u64(body, 6 + 16 * k) for k in range((len(body) - 6) // 16)]
                at = end
                continue
            yield from self._settle()
            if opcode == Opcode.CHUNK:
                records, intact = _chunk_records(body) or (b'', False)
                try:
                    if not intact:
                        raise ValueError('the chunk does not match its CRC')
                    self._pending = self._from_records(records)
                except MCAP_DAMAGE:
                    self._damaged = (_u64(body, 0), _u64(body, 8))   # its indexes: how many
            elif opcode in (Opcode.SCHEMA, Opcode.CHANNEL, Opcode.MESSAGE):
                yield from self._from_records(data[at:end].tobytes())
                self._orphans = 0   # outside a chunk: no index counts them again
            elif opcode in (Opcode.DATA_END, Opcode.FOOTER):
                complete = True
                break
            at = end
        yield from self._settle()
        self.report.cut_short = not complete
        self._close_stretch(None)
        if self.total is not None:
            self._count_from_summary(self.total)

    def _count_from_summary(self, total: int) -> None:
        """A finished file says how many messages it held: what no index counted is the rest,
        said of the one stretch whose count was unknown (none lost: those stretches lost
        nothing, an index's bytes, say)."""
        stretches = self.report.stretches
        counted = sum(s.count or 0 for s in stretches)
        unknown = [k for k, s in enumerate(stretches) if s.count is None]
        rest = total - self.seen - counted
        if rest == 0 and unknown:
            self.report.stretches = [s for s in stretches if s.count is not None]
            self.report.damaged_chunks -= len(unknown)
        elif len(unknown) == 1:
            stretches[unknown[0]] = dataclasses.replace(stretches[unknown[0]], count=rest)
        self.report.dropped = max(self.report.dropped, total - self.seen)

    def _settle(self) -> Iterator[Stored]:
        """The chunk read last, now that its indexes have said how many messages it held."""
        pending, self._pending = self._pending, []
        indexed, self._indexed = self._indexed, []
        damaged, self._damaged = self._damaged, None
        read, self._orphans = len(pending) + self._orphans, 0   # orphans: counted already
        if damaged is not None or len(indexed) > read:
            count = len(indexed) - read if indexed else None
            self._lose(count, [*(damaged or ()), *indexed])
        if pending:
            self._close_stretch(pending[0][2])
        yield from pending

    def _lose(self, count: int | None, times: list[int] | None = None) -> None:
        """Messages lost here: ``count`` of them (None: the file does not say), at ``times``."""
        if self._stretch is None:
            self._stretch = _Stretch(self.last_ns)
            self.report.damaged_chunks += 1
        stretch = self._stretch
        if count is not None:
            self.report.dropped += count
        stretch.count = None if count is None or stretch.count is None else stretch.count + count
        stretch.times += times or []

    def _close_stretch(self, next_ns: int | None) -> None:
        """The first intact message after a loss (None: the end of the file)."""
        stretch, self._stretch = self._stretch, None
        if stretch is None:
            return
        times = stretch.times
        self.report.stretches.append(DroppedStretch(
            stretch.count, min(times) if times else stretch.after_ns,
            max(times) if times else next_ns))

    # -- records -----------------------------------------------------------------------------
    def _checked(self, at: int, strict: bool = False) -> memoryview | None:
        """The body of the record at ``at`` if its framing checks out: a known opcode, a length
        within the file that agrees with what the body says of itself (``strict``: and a chunk's
        CRC with its records, for a record found by searching)."""
        data = self.data
        if at + 9 > len(data):
            return None
        opcode, length = data[at], _u64(data, at + 1)
        if not 0 < opcode <= _LAST_OPCODE or length > RECORD_SIZE_LIMIT \
                or at + 9 + length > len(data):
            return None
        body = data[at + 9:at + 9 + length]
        if opcode == Opcode.CHUNK:
            records = _chunk_records(body)
            return body if records is not None and (records[1] or not strict) else None
        if opcode == Opcode.MESSAGE_INDEX:
            if length < 6 or _u32(body, 2) != length - 6 or (length - 6) % 16:
                return None
            offsets = [_u64(body, 14 + 16 * k) for k in range((length - 6) // 16)]
            known = not self.channels or int.from_bytes(body[:2], 'little') in self.channels
            return body if known and offsets == sorted(set(offsets)) else None
        if opcode == Opcode.DATA_END:
            return body if length == 4 else None
        if opcode == Opcode.MESSAGE:
            return body if length >= 22 else None
        shape = _SHAPES.get(Opcode(opcode))
        return body if not strict and shape is not None and _fills(body, shape) else None

    def _from_records(self, records: bytes) -> list[Stored]:
        """The messages among ``records`` (a chunk's, or records of the data section); schemas
        and channels are learnt on the way. A message whose channel is unknown (its record was
        in a chunk that is lost) is dropped and counted.

        Raises
        ------
        ValueError
            A record runs past the end of ``records``: none of their messages is taken.
        """
        from mcap.data_stream import ReadDataStream
        from mcap.records import Channel, Schema

        messages: list[Stored] = []
        orphans: list[int] = []
        at = 0
        while at + 9 <= len(records):
            opcode, length = records[at], _u64(records, at + 1)
            body = records[at + 9:at + 9 + length]
            if len(body) != length:
                raise ValueError('a record runs past its chunk')
            if opcode == Opcode.SCHEMA:
                schema = Schema.read(ReadDataStream(io.BytesIO(body)))
                self.schemas[schema.id] = schema.name
            elif opcode == Opcode.CHANNEL:
                channel = Channel.read(ReadDataStream(io.BytesIO(body)))
                self.channels[channel.id] = (channel.topic, self.schemas[channel.schema_id])
            elif opcode == Opcode.MESSAGE:
                channel_id, log_time = int.from_bytes(body[:2], 'little'), _u64(body, 6)
                if channel_id in self.channels:
                    messages.append((*self.channels[channel_id], log_time, body[22:]))
                else:
                    orphans.append(log_time)
            at += 9 + length
        self.seen += len(messages)
        if orphans:
            self._lose(len(orphans), orphans)
            self._orphans += len(orphans)
        if messages:
            self.last_ns = messages[-1][2]
        return messages

    def _chunk_end_by_header(self, at: int) -> int | None:
        """Where the chunk at ``at`` ends by its header (its compression name's and records'
        lengths), if a record that checks out strictly starts there (or the file ends)."""
        data = self.data
        if at + 9 + 40 > len(data):
            return None
        name_length = _u32(data, at + 9 + 28)
        if at + 9 + 40 + name_length > len(data):
            return None
        end = at + 9 + 40 + name_length + _u64(data, at + 9 + 32 + name_length)
        if end > len(data) or (end < len(data) and self._checked(end, strict=True) is None):
            return None
        return end

    def _resync(self, start: int) -> int | None:
        """The first record at or after ``start`` that checks out and that only a whole record
        starts with: a chunk (its CRC), a message index (its lengths agree), the data's end."""
        data, found = self.data, {}
        raw = data.obj if isinstance(data.obj, (bytes, mmap.mmap)) else bytes(data)
        for opcode in (Opcode.CHUNK, Opcode.MESSAGE_INDEX, Opcode.DATA_END):
            found[opcode] = raw.find(bytes([opcode]), start)
        while True:
            candidates = [(at, opcode) for opcode, at in found.items() if at >= 0]
            if not candidates:
                return None
            at, opcode = min(candidates)
            if self._checked(at, strict=True) is not None:
                return at
            found[opcode] = raw.find(bytes([opcode]), at + 1)

    def _read_summary(self) -> None:
        """Schemas, channels and the message count from a finished file's summary section: the
        channels stay known when the chunk that first named them is lost."""
        from mcap.data_stream import ReadDataStream
        from mcap.records import Channel, Schema, Statistics

        data = self.data
        footer = len(data) - len(MAGIC) - FOOTER_SIZE
        if footer < len(MAGIC) or bytes(data[-len(MAGIC):]) != MAGIC \
                or data[footer] != Opcode.FOOTER:
            return
        at, end = _u64(data, footer + 9), footer
        if not len(MAGIC) <= at < end:
            return
        with contextlib.suppress(*MCAP_DAMAGE, IndexError):
            while at + 9 <= end:
                opcode, length = data[at], _u64(data, at + 1)
                stream = ReadDataStream(io.BytesIO(data[at + 9:at + 9 + length].tobytes()))
                if opcode == Opcode.SCHEMA:
                    schema = Schema.read(stream)
                    self.schemas[schema.id] = schema.name
                elif opcode == Opcode.CHANNEL:
                    channel = Channel.read(stream)
                    self.channels[channel.id] = (channel.topic, self.schemas[channel.schema_id])
                elif opcode == Opcode.STATISTICS:
                    statistics = Statistics.read(stream)
                    # The summary has no CRC (rosbags writes 0): its count is trusted only if it
                    # agrees with its per-channel counts and fits in the file.
                    count = statistics.message_count
                    if count == sum(statistics.channel_message_counts.values()) \
                            and count <= len(data) // _SMALLEST_MESSAGE:
                        self.total = count
                at += 9 + length


def mcap_messages(path: Path, report: Recovery) -> Iterator[Stored]:
    """Every message of every intact chunk of an mcap file, footer or not, the chunks after a
    damaged one included (:class:`_McapSalvage`)."""
    with open(path, 'rb') as stream:
        if os.fstat(stream.fileno()).st_size == 0:
            report.cut_short = True
            return
        with mmap.mmap(stream.fileno(), 0, access=mmap.ACCESS_READ) as mapped:
            view = memoryview(mapped)
            try:
                yield from _McapSalvage(view, report).messages()
            finally:
                view.release()
