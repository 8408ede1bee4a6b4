"""A recording whose disk fills up: the run stops with one line (the disk is full, where), exits
1, and leaves one bag holding what reached the disk (no second half-bag, no traceback)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

from omni_micro_tools.bag_reading import read_bag
from omni_micro_tools.bags import recover
from omni_micro_tools.errors import BagDamagedError


@pytest.fixture
def small_disk(tmp_path: Path):
    """A 200 kB file system of its own (a tmpfs; mounting needs root, which CI has)."""
    mount_point = tmp_path / 'small'
    mount_point.mkdir()
    if os.geteuid() != 0:
        pytest.skip('mounting a small tmpfs needs root')
    subprocess.run(['mount', '-t', 'tmpfs', '-o', 'size=200k', 'tmpfs', str(mount_point)],
                   check=True)
    try:
        yield mount_point
    finally:
        subprocess.run(['umount', '-l', str(mount_point)], check=False)


def test_a_full_disk_stops_the_run_in_one_line_and_leaves_one_bag(small_disk, tmp_path,
                                                                   omni_micro):
    bag = small_disk / 'bag'
    done = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--quiet', '--record',
                      str(bag), '--log-dir', str(tmp_path / 'logs'))
    assert done.returncode == 1, done.stderr[-3000:]
    lines = done.stderr.strip().splitlines()
    assert 'Traceback' not in done.stderr
    assert lines[-1].startswith('omni-micro run: failed: bag_recorder cannot write')
    assert str(bag) in lines[-1] and 'No space left on device' in lines[-1]
    assert 'bag-recover' in lines[-1]
    # One bag, as the recorder left it: what reached the disk, recoverable elsewhere.
    assert [path.name for path in small_disk.iterdir()] == ['bag']
    # About a second of simulated time fits: its last second is the unsure tail, which plain
    # recovery leaves out (all of it, when less fitted: then it says so) and can be kept.
    try:
        plain = recover(bag, tmp_path / 'plain')
        assert plain.unsure_tail > 0
    except BagDamagedError as error:
        assert '--keep-unsure-tail keeps them' in str(error)
    report = recover(bag, tmp_path / 'recovered', keep_unsure_tail=True)
    assert report.kept >= 1 and report.unsure_tail == 0
    assert sum(len(messages) for messages in
               read_bag(tmp_path / 'recovered').messages.values()) == report.kept
