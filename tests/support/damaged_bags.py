"""Bags damaged as a killed recorder, a copy cut short or a bad disk leaves them: written, then
cut or overwritten where a test says (tests/tools/test_damaged_bags.py, and the commands' lines
about them in tests/cli/test_damaged_bag_commands.py)."""

from __future__ import annotations

from pathlib import Path

from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message

from omni_micro_tools.bags import flush, open_writer
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


def overwrite(bag: Path, at: int, length: int, value: int = 0xFF) -> None:
    data = bytearray(mcap_of(bag).read_bytes())
    data[at:at + length] = bytes([value]) * len(data[at:at + length])
    mcap_of(bag).write_bytes(bytes(data))
