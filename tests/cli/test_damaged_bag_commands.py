"""What each command says of a damaged bag: one line, naming the bag, and nothing written
(bag-recover: how many messages it dropped, and when). The bags: tests/support/damaged_bags.py;
the reading and recovery themselves: tests/tools/test_damaged_bags.py."""

from __future__ import annotations

from pathlib import Path

import pytest
from damaged_bags import (
    CHUNKS,
    PER_CHUNK,
    chunk_offsets,
    damage_second_chunk,
    flip_bytes_in_third_chunks_messages,
    mcap_of,
    overwrite,
    truncate,
    write_bag,
)

from omni_micro_cli.cli import main
from omni_micro_tools.bags import recover


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / 'bag'
    write_bag(path)
    return path


@pytest.mark.parametrize('command', ['analyze', 'identify', 'replay', 'track'])
def test_every_bag_command_fails_in_one_line_on_a_cut_short_bag(bag, command, tmp_path, capsys):
    truncate(bag)
    extra = ['--out', str(tmp_path / 'out')] if command == 'analyze' else []
    assert main([command, str(bag), *extra]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f'omni-micro {command}: failed: bag ')
    assert 'Traceback' not in err[0]
    assert not (tmp_path / 'out').exists()


def test_bag_recover_says_how_many_it_dropped(bag, tmp_path, capsys):
    damage_second_chunk(bag)
    assert main(['bag-recover', str(bag), '--out', str(tmp_path / 'r')]) == 0
    err = capsys.readouterr().err
    assert 'recovered ' in err and 'dropped ' in err


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
    assert report.kept == (CHUNKS - 1) * PER_CHUNK and report.damaged_chunks == 1


def test_bag_recover_names_the_times_of_what_it_dropped(bag, tmp_path, capsys):
    second = chunk_offsets(mcap_of(bag).read_bytes())[1]
    overwrite(bag, second, 64)
    assert main(['bag-recover', str(bag), '--out', str(tmp_path / 'r')]) == 0
    err = capsys.readouterr().err
    assert f'dropped {PER_CHUNK} messages: {PER_CHUNK} between ' in err
