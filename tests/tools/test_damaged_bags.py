"""Bags as they come back from a killed recorder, a copy cut short or a bad disk: every reader
says in one line which bag and what is wrong (and how to recover it), and bag-recover keeps
every intact chunk and counts the messages it dropped (what each command prints of it:
tests/cli/test_damaged_bag_commands.py)."""

from __future__ import annotations

import functools
import itertools
import struct
import tempfile
from pathlib import Path

import pytest
from damaged_bags import (
    CHUNKS,
    PER_CHUNK,
    break_metadata,
    chunk_offsets,
    damage_second_chunk,
    mcap_of,
    overwrite,
    truncate,
    write_bag,
)
from hypothesis import given, settings
from hypothesis import strategies as st

from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.bag_salvage import reader_of
from omni_micro_tools.bags import recover
from omni_micro_tools.errors import BagDamagedError
from omni_micro_tools.salvage_report import Recovery


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / 'bag'
    write_bag(path)
    assert len(read_bag(path).messages['/odom']) == CHUNKS * PER_CHUNK
    return path


@pytest.mark.parametrize(('damage', 'says'), [
    (truncate, 'looks cut short'),
    (break_metadata, 'metadata.yaml'),
])
def test_a_damaged_bag_is_named_with_what_is_wrong_and_how_to_recover_it(bag, damage, says):
    damage(bag)
    with pytest.raises(BagDamagedError) as error:
        read_bag(bag)
    text = str(error.value)
    assert str(bag) in text and says in text and f'omni-micro bag-recover {bag}' in text
    assert '\n' not in text


def test_recovery_of_a_cut_short_bag_keeps_every_whole_chunk(bag, tmp_path):
    truncate(bag)
    report = recover(bag, tmp_path / 'recovered')
    assert report.cut_short
    kept = read_bag(tmp_path / 'recovered').messages['/odom']
    # Cut at 5/8 of the file: at least the first two chunks whole, nothing invented; the last
    # second of simulated time (one message here) left out, as it may have been incomplete.
    assert report.unsure_tail == 1
    assert 2 * PER_CHUNK <= len(kept) + 1 == report.kept + 1 < CHUNKS * PER_CHUNK
    assert [m.header.stamp.sec for m in kept] == list(range(len(kept)))


def test_recovery_skips_a_damaged_chunk_and_counts_what_it_dropped(bag, tmp_path):
    damage_second_chunk(bag)
    report = recover(bag, tmp_path / 'recovered')
    kept = read_bag(tmp_path / 'recovered').messages['/odom']
    stamps = [m.header.stamp.sec for m in kept]
    assert report.damaged_chunks == 1 and not report.cut_short
    # A file its recorder finished (its footer is there) keeps its last second: nothing in it
    # was on its way when the recorder stopped.
    assert report.dropped == PER_CHUNK and report.kept == (CHUNKS - 1) * PER_CHUNK
    assert len(stamps) == report.kept and report.unsure_tail == 0
    # The first and the last chunk are intact: all of theirs are back, in order.
    assert stamps[:PER_CHUNK] == list(range(PER_CHUNK))
    assert stamps[-PER_CHUNK:] == list(range((CHUNKS - 1) * PER_CHUNK, CHUNKS * PER_CHUNK))


def footer_of(data: bytes) -> tuple[int, int]:
    """Where the summary section starts and where the data section's end record does."""
    footer = len(data) - 8 - 29
    summary = int.from_bytes(data[footer + 9:footer + 17], 'little')
    return summary, summary - 13


def as_killed(bag: Path) -> None:
    """The bag as a recorder killed after its last flush leaves it: no summary, no footer, no
    metadata.yaml."""
    data = mcap_of(bag).read_bytes()
    mcap_of(bag).write_bytes(data[:footer_of(data)[1]])
    (bag / 'metadata.yaml').unlink()


def kept_stamps(recovered: Path) -> list[int]:
    return [m.header.stamp.sec for m in read_bag(recovered).messages.get('/odom', [])]


def test_a_chunk_whose_length_alone_was_overwritten_is_read_whole_by_its_header(bag, tmp_path):
    """The walk used to stop there, keeping nothing after it: the chunk's header says where it
    ends, a record checks out there, and its CRC vouches for its records."""
    data = mcap_of(bag).read_bytes()
    second = chunk_offsets(data)[1]
    overwrite(bag, second + 1, 8, 0x7F)
    report = recover(bag, tmp_path / 'recovered', keep_unsure_tail=True)
    assert report.dropped == 0 and report.damaged_chunks == 0 and not report.cut_short
    assert kept_stamps(tmp_path / 'recovered') == list(range(CHUNKS * PER_CHUNK))


@pytest.mark.parametrize('killed', [False, True], ids=['finished', 'killed'])
def test_the_chunks_after_a_damaged_stretch_are_kept_and_the_loss_is_placed_in_time(
        bag, tmp_path, killed):
    """64 bytes of bad sectors over the second chunk's header: its framing is gone. The walk
    finds the next record that checks out and keeps the third and fourth chunks whole. A
    finished file's statistics say how many the stretch held; a killed recorder's file does not
    (its indexes cannot be told from a part of another chunk's), and that is what is said."""
    data = mcap_of(bag).read_bytes()
    second = chunk_offsets(data)[1]
    if killed:
        as_killed(bag)
    overwrite(bag, second, 64)
    report = recover(bag, tmp_path / 'recovered', keep_unsure_tail=True)
    stamps = kept_stamps(tmp_path / 'recovered')
    assert stamps == [*range(PER_CHUNK), *range(2 * PER_CHUNK, CHUNKS * PER_CHUNK)]
    assert report.damaged_chunks == 1 and len(report.stretches) == 1
    (stretch,) = report.stretches
    # Between the last message kept before it and the first kept after it (log times: index).
    assert stretch.from_ns is not None and stretch.to_ns is not None
    assert stretch.from_ns >= PER_CHUNK - 1 and stretch.to_ns <= 2 * PER_CHUNK
    assert report.cut_short is killed
    if killed:
        assert stretch.count is None and 'an unknown number between' in stretch.said()
    else:
        assert stretch.count == report.dropped == PER_CHUNK
        assert stretch.said() == f'{PER_CHUNK} between {stretch.from_ns * 1e-9:.3f} s and ' \
                                 f'{stretch.to_ns * 1e-9:.3f} s'


@functools.cache
def pristine() -> bytes:
    """The bytes of the bag the fixture writes, written once."""
    with tempfile.TemporaryDirectory() as work:
        write_bag(Path(work) / 'bag')
        return mcap_of(Path(work) / 'bag').read_bytes()


@settings(max_examples=200, deadline=None)
@given(where=st.floats(0.0, 1.0), length=st.integers(1, 3000), value=st.integers(0, 255),
       killed=st.booleans())
def test_any_damage_keeps_every_chunk_it_did_not_touch_and_invents_nothing(where, length,
                                                                            value, killed):
    """Bytes overwritten anywhere, of any length, in a finished file or a killed recorder's: the
    salvage never fails, every message it reads is one the bag held (its stamp, at most once),
    every chunk the damage did not touch is read whole, and read + dropped never exceeds what
    the bag held (and, while a finished file's summary is intact, is exactly that)."""
    summary, data_end = footer_of(pristine())
    data = bytearray(pristine()[:data_end] if killed else pristine())
    at = round(where * (len(data) - 1))
    data[at:at + length] = bytes([value]) * len(data[at:at + length])
    report = Recovery({})
    with tempfile.TemporaryDirectory() as work:
        file = Path(work) / 'bag.mcap'
        file.write_bytes(bytes(data))
        stamps = [struct.unpack_from('<i', message, 4)[0]
                  for _, _, _, message in reader_of(file, report)()]
    assert len(stamps) == len(set(stamps))
    assert set(stamps) <= set(range(CHUNKS * PER_CHUNK))
    offsets = [*chunk_offsets(pristine()), data_end]
    # The first chunk names the channels; without a summary nothing else does: with it lost,
    # a killed recorder's later messages are of no known topic (dropped, and counted).
    channels_lost = killed and at < offsets[1]
    for index, (start, end) in enumerate(itertools.pairwise(offsets)):
        if (at + length <= start or end <= at) and not channels_lost:
            chunk = set(range(index * PER_CHUNK, (index + 1) * PER_CHUNK))
            assert chunk <= set(stamps), f'chunk {index} was not touched'
    assert len(stamps) + report.dropped <= CHUNKS * PER_CHUNK
    if not killed and at + length <= summary:   # the summary (its statistics) untouched
        assert len(stamps) + report.dropped == CHUNKS * PER_CHUNK
