"""What a graph's stop removes from /dev/shm: a killed process's orphaned Fast DDS port, made by
whichever run, and nothing a living process maps or listens on."""

from __future__ import annotations

import mmap
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from omni_micro_bringup import shared_memory

SHM = Path('/dev/shm')


@pytest.fixture
def port_file():
    """Makes port files under names no participant takes (Fast DDS numbers its ports from 7000)
    and removes whatever the test left."""
    made: list[Path] = []

    def make(name: str) -> Path:
        path = SHM / name
        path.write_bytes(b'\0' * 4096)
        made.append(path)
        return path
    yield make
    for path in made:
        path.unlink(missing_ok=True)


@pytest.mark.skipif(not SHM.is_dir(), reason='no /dev/shm on this system')
def test_an_orphaned_port_goes_whoever_made_it_and_a_port_in_use_stays(port_file, monkeypatch):
    # Only this function's own rule, not the fastdds tool's cleaning of dead owners' segments.
    monkeypatch.setattr(shared_memory.shutil, 'which', lambda *args, **kwargs: None)
    first = 900_000_000 + uuid.uuid4().int % 10**8 * 3
    orphan = port_file(f'fastrtps_port{first}')          # there before the run or not: alike
    listened = port_file(f'fastrtps_port{first + 1}')
    lock = port_file(f'fastrtps_port{first + 1}_el')
    mapped = port_file(f'fastrtps_port{first + 2}')      # a writer opened it before any reader
    with open(mapped, 'r+b') as handle, mmap.mmap(handle.fileno(), 4096):
        assert mapped.name in shared_memory.shared_memory_files_in_use()
        shared_memory.clean_shared_memory()
        assert mapped.exists()
    assert not orphan.exists()
    assert listened.exists() and lock.exists()


def test_only_a_graph_with_a_death_in_it_cleans_what_others_may_be_opening():
    assert not shared_memory.left_shared_memory({'dynamics_node': 0, 'vision_node': 0}, [1, 1])
    assert shared_memory.left_shared_memory({'dynamics_node': 0, 'vision_node': -9}, [1, 1])
    assert shared_memory.left_shared_memory({'dynamics_node': 0, 'vision_node': 0}, [1, 2])
    assert shared_memory.left_shared_memory({'dynamics_node': None}, [1])


@pytest.mark.skipif(not SHM.is_dir(), reason='no /dev/shm on this system')
def test_a_port_another_process_took_stays_and_is_named_with_who_holds_it(port_file, monkeypatch):
    """Fast DDS leaves a port a killed writer had opened when its reader closes, and the next
    participant of any domain takes that same file: the cleaning leaves it to that process and
    says so (tests/graph/test_shared_memory_reuse.py shows Fast DDS doing it)."""
    monkeypatch.setattr(shared_memory.shutil, 'which', lambda *args, **kwargs: None)
    first = 900_000_000 + uuid.uuid4().int % 10**8 * 3
    taken = port_file(f'fastrtps_port{first}')
    orphan = port_file(f'fastrtps_port{first + 1}')
    used = shared_memory.shared_memory_identities({taken.name, orphan.name})
    holder = subprocess.Popen(
        [sys.executable, '-c', 'import mmap, sys; f = open(sys.argv[1], "r+b"); '
         'm = mmap.mmap(f.fileno(), 4096); print("mapped", flush=True); sys.stdin.read()',
         str(taken)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == 'mapped'
        assert shared_memory.clean_shared_memory(used, graph_pids=[]) == {
            taken.name: {holder.pid}}
        assert taken.exists() and not orphan.exists()
        # Held by one of the graph's own processes, it is not another graph's.
        assert shared_memory.clean_shared_memory(used, graph_pids=[holder.pid]) == {}
    finally:
        holder.communicate('')
    # Let go, it is an orphan like any other.
    assert shared_memory.clean_shared_memory(used, graph_pids=[]) == {}
    assert not taken.exists()


@pytest.mark.skipif(not SHM.is_dir(), reason='no /dev/shm on this system')
def test_a_port_whose_lock_file_another_process_holds_is_taken_before_it_maps_the_port(
        port_file, monkeypatch):
    """A participant takes a port's lock file, then maps the port (and unmaps it, then lets the
    lock go, as it closes): in between, the port is that process's all the same. Counted as an
    orphan, it was left as the graph's own leftover once that process let it go (a killed
    writer's count keeps it in /dev/shm)."""
    monkeypatch.setattr(shared_memory.shutil, 'which', lambda *args, **kwargs: None)
    first = 900_000_000 + uuid.uuid4().int % 10**8 * 3
    port = port_file(f'fastrtps_port{first}')
    lock = port_file(f'fastrtps_port{first}_el')
    used = shared_memory.shared_memory_identities({port.name})
    holder = subprocess.Popen(
        [sys.executable, '-c', 'import sys; f = open(sys.argv[1], "r+b"); '
         'print("locked", flush=True); sys.stdin.read()', str(lock)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout is not None and holder.stdout.readline().strip() == 'locked'
        assert shared_memory.clean_shared_memory(used, graph_pids=[]) == {port.name: {holder.pid}}
        assert port.exists() and lock.exists()
    finally:
        holder.communicate('')
