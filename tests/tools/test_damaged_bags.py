"""Bags as they come back from a killed recorder, a copy cut short or a bad disk: every reader
says in one line which bag and what is wrong (and how to recover it), and bag-recover keeps
every intact chunk and says how many messages it dropped."""

from __future__ import annotations

from pathlib import Path

import pytest
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message

from omni_micro_cli.cli import main
from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.bags import flush, open_writer, recover
from omni_micro_tools.errors import BagDamagedError
from omni_micro_tools.topics import GRAPH_TOPICS

CHUNKS, PER_CHUNK = 4, 50


def write_bag(path: Path) -> None:
    """A bag of CHUNKS chunks of PER_CHUNK odometry messages (the recorder flushes a chunk
    every 0.5 s in the same way)."""
    writer, connections = open_writer(path, 'mcap', {'/odom': GRAPH_TOPICS['/odom']})
    for index in range(CHUNKS * PER_CHUNK):
        message = Odometry()
        message.header.stamp.sec = index
        message.pose.pose.position.x = index * 1e-3
        writer.write(connections['/odom'], index, serialize_message(message))
        if index % PER_CHUNK == PER_CHUNK - 1:
            flush(writer)
    writer.close()


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / 'bag'
    write_bag(path)
    assert len(read_bag(path).messages['/odom']) == CHUNKS * PER_CHUNK
    return path


def mcap_of(bag: Path) -> Path:
    (path,) = bag.glob('*.mcap')
    return path


def truncate(bag: Path) -> None:
    data = mcap_of(bag).read_bytes()
    mcap_of(bag).write_bytes(data[:len(data) * 5 // 8])


def chunk_offsets(data: bytes) -> list[int]:
    """Where each chunk record starts (after the 8-byte magic: opcode, length, body)."""
    offsets, at = [], 8
    while at + 9 <= len(data):
        opcode, length = data[at], int.from_bytes(data[at + 1:at + 9], 'little')
        if opcode == 0x06:
            offsets.append(at)
        at += 9 + length
    return offsets


def damage_second_chunk(bag: Path) -> None:
    """Overwrite the length of the second chunk's first record, as a bad sector would: that
    chunk no longer parses, its neighbours do."""
    data = bytearray(mcap_of(bag).read_bytes())
    second = chunk_offsets(bytes(data))[1]
    body = second + 9
    compression_length = int.from_bytes(data[body + 28:body + 32], 'little')
    first_record = body + 32 + compression_length + 8
    data[first_record + 1:first_record + 9] = (1 << 40).to_bytes(8, 'little')
    mcap_of(bag).write_bytes(bytes(data))


def break_metadata(bag: Path) -> None:
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed\n  : :')


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


@pytest.mark.parametrize('command', ['analyze', 'identify', 'replay', 'track'])
def test_every_bag_command_fails_in_one_line_on_a_cut_short_bag(bag, command, tmp_path, capsys):
    truncate(bag)
    extra = ['--out', str(tmp_path / 'out')] if command == 'analyze' else []
    assert main([command, str(bag), *extra]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'omni-micro {command}: failed: bag ')
    assert 'Traceback' not in err[0]
    assert not (tmp_path / 'out').exists()


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
    assert report.dropped == PER_CHUNK and report.kept == (CHUNKS - 1) * PER_CHUNK - 1
    assert len(stamps) == report.kept and report.unsure_tail == 1
    # The first and the last chunk are intact: all of theirs are back, in order (but the last
    # second's).
    assert stamps[:PER_CHUNK] == list(range(PER_CHUNK))
    assert stamps[-PER_CHUNK + 1:] == list(range((CHUNKS - 1) * PER_CHUNK,
                                                 CHUNKS * PER_CHUNK - 1))


def test_bag_recover_says_how_many_it_dropped(bag, tmp_path, capsys):
    damage_second_chunk(bag)
    assert main(['bag-recover', str(bag), '--out', str(tmp_path / 'r')]) == 0
    err = capsys.readouterr().err
    assert 'recovered ' in err and 'dropped ' in err


def flip_bytes_in_third_chunks_messages(bag: Path) -> None:
    """Twenty bytes flipped inside the third chunk's message data: every message still
    decodes, with wrong values (what the round-3 report saw: exit 0 on wrong numbers)."""
    data = bytearray(mcap_of(bag).read_bytes())
    third = chunk_offsets(bytes(data))[2]
    length = int.from_bytes(data[third + 1:third + 9], 'little')
    middle = third + 9 + length // 2
    for k in range(20):
        data[middle + 3 * k] ^= 0xFF
    mcap_of(bag).write_bytes(bytes(data))


@pytest.mark.parametrize('command', ['analyze', 'replay'])
def test_bytes_flipped_in_message_data_are_caught_by_the_chunks_crc(bag, command, tmp_path,
                                                                    capsys):
    """Every chunk carries its CRC32 (rosbag2's mcap writer's default; rosbags wrote none):
    a command refuses the bag in one line naming the chunk, and bag-recover keeps the rest.
    (identify reads the moves and captures only: the chunks it reads are checked the same.)"""
    from mcap.reader import make_reader
    from mcap.stream_reader import CRCValidationError

    flip_bytes_in_third_chunks_messages(bag)
    # The independent reader finds it too.
    with open(mcap_of(bag), 'rb') as stream, pytest.raises(CRCValidationError):
        list(make_reader(stream, validate_crcs=True).iter_messages())
    argv = {'analyze': ['analyze', str(bag), '--out', str(tmp_path / 'a')],
            'replay': ['replay', str(bag), '--topics', '/odom']}[command]
    assert main(argv) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert ('is damaged: Chunk checksum mismatch in chunk 3 of 4 of bag.mcap (messages from '
            '0.000 to 0.000 s)') in err, err
    report = recover(bag, tmp_path / 'recovered')
    assert report.kept == (CHUNKS - 1) * PER_CHUNK - 1 and report.damaged_chunks == 1
