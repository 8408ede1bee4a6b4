"""Bag paths as a newcomer types them: nested output folders are made, and a path that is not a
readable bag says why and what to do."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from omni_micro_tools.bag_reading import check_readable_bag
from omni_micro_tools.bags import check_bag_output
from omni_micro_tools.errors import BagPathError

ROOT = Path(__file__).resolve().parents[2]


def test_the_folders_of_a_new_bag_are_made(tmp_path):
    bag = tmp_path / 'out' / 'bags' / 'fig11'
    check_bag_output(bag, force=False)
    assert bag.parent.is_dir() and not bag.exists()


def test_an_existing_bag_is_still_refused_naming_it(tmp_path):
    bag = tmp_path / 'mine'
    bag.mkdir()
    with pytest.raises(BagPathError, match=f"'{bag}' exists already"):
        check_bag_output(bag, force=False)


def test_a_path_that_does_not_exist_says_so(tmp_path):
    with pytest.raises(BagPathError, match='does not exist') as error:
        check_readable_bag(tmp_path / 'nope')
    assert 'bag-recover' not in str(error.value)


def test_only_a_torn_bag_is_sent_to_bag_recover(tmp_path):
    torn = tmp_path / 'torn'
    torn.mkdir()
    (torn / 'torn_0.mcap').write_bytes(b'\x89MCAP0\r\n')
    with pytest.raises(BagPathError, match=f'omni-micro bag-recover {torn}'):
        check_readable_bag(torn)
    empty = tmp_path / 'empty'
    empty.mkdir()
    with pytest.raises(BagPathError, match='is not a bag') as error:
        check_readable_bag(empty)
    assert 'bag-recover' not in str(error.value)
    with pytest.raises(BagPathError, match='is a file'):
        check_readable_bag(torn / 'torn_0.mcap')


@pytest.mark.slow   # starts omni-micro as a process
@pytest.mark.parametrize('command', ['analyze', 'analyse', 'replay'])
def test_analyze_and_replay_of_a_missing_bag_exit_2(command, tmp_path):
    args = [str(ROOT / 'scripts' / 'omni-micro'), command, str(tmp_path / 'nope')]
    if command != 'replay':
        args += ['--out', str(tmp_path / 'figs')]
    result = subprocess.run(args, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2 and 'does not exist' in result.stderr, result.stderr
    assert not (tmp_path / 'figs').exists()
