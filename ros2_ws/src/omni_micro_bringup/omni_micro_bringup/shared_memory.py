"""Fast DDS shared-memory files in /dev/shm: who holds them, and what a killed process left."""

from __future__ import annotations

import contextlib
import os
import shutil
import subprocess
import sys
from collections.abc import Collection
from collections.abc import Set as AbstractSet
from pathlib import Path

SHM = Path('/dev/shm')


def shared_memory_files() -> set[str]:
    return {path.name for path in SHM.glob('*fastrtps*')} if SHM.is_dir() else set()


def shared_memory_holders(pids: list[int] | None = None) -> dict[str, set[int]]:
    """Each Fast DDS shared-memory file some living process (of ``pids``: any this user may read)
    maps (its segments and ports) or holds open (their ``_el`` lock files), and who does."""
    holders: dict[str, set[int]] = {}
    processes = (Path('/proc').glob('[0-9]*') if pids is None
                 else [Path(f'/proc/{pid}') for pid in pids])
    for process in processes:
        try:
            held = {line.rsplit('/', 1)[-1]
                    for line in (process / 'maps').read_text().splitlines()
                    if '/dev/shm/fastrtps' in line}
            descriptors = list((process / 'fd').iterdir())
        except OSError:   # the process ended while we looked, or is not ours to read
            continue
        for fd in descriptors:
            with contextlib.suppress(OSError):   # closed while we looked (listing's own, too)
                target = os.readlink(fd)
                if target.startswith('/dev/shm/fastrtps'):
                    held.add(target.rsplit('/', 1)[-1])
        for name in held:
            holders.setdefault(name, set()).add(int(process.name))
    return holders


def shared_memory_files_in_use(pids: list[int] | None = None) -> set[str]:
    return set(shared_memory_holders(pids))


def shared_memory_identities(names: set[str]) -> set[tuple[str, int]]:
    """Each file's name and inode: a file of the same name made again later is another file."""
    found = set()
    for name in names:
        try:
            found.add((name, (SHM / name).stat().st_ino))
        except FileNotFoundError:
            continue
    return found


def left_shared_memory(codes: dict[str, int | None], starts: list[int]) -> bool:
    """Whether a graph's processes may have left shared-memory files: one did not stop on its
    signal with code 0 (killed, crashed, stuck), or one was started again after dying."""
    return any(code != 0 for code in codes.values()) or any(count > 1 for count in starts)


def clean_shared_memory(used: AbstractSet[tuple[str, int]] = frozenset(),
                        graph_pids: Collection[int] = ()) -> dict[str, set[int]]:
    """Remove the Fast DDS shared-memory files a killed process left behind; returns those of
    the files a graph's processes used (``used``, by name and inode) that are still there because
    processes outside the graph (``graph_pids``) hold them, and who.

    `fastdds shm clean` removes segments and ports whose owner died (a SIGKILL leaves them).
    It leaves port files with no `_el` lock file: nobody listens on those any more, yet they
    stay in /dev/shm. Those are removed too when no process maps them (a writer that opened a
    port before its reader still does), whoever made them: every participant takes the first
    free of fastrtps_port7000, 7001, ... whatever its domain, so a port one run's killed
    process left is the next one's, of any run, and a process killed there leaves it again
    under a name the second run had not made.

    Fast DDS removes a port when the last process that opened it closes it, counting openers in
    the port itself: a writer killed with a reader's port open keeps that count up for ever, so
    the port outlives its reader's normal exit. Every new participant of any domain takes the
    first free of those ports as it is (the same file, measured) and leaves it in turn when it
    closes: taken while the graph stopped, it is that process's to use, not this one's to remove.
    A port counts as taken by whoever maps it or holds its lock file.
    """
    tool = shutil.which('fastdds', path=str(Path(sys.prefix) / 'bin'))
    if tool:
        subprocess.run([tool, 'shm', 'clean'], stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, timeout=30, check=False)
    orphans = {name for name in shared_memory_files()
               if name.startswith('fastrtps_port') and not name.endswith('_el')
               and not (SHM / f'{name}_el').exists()}
    if orphans:   # reading every process's maps costs tens of milliseconds
        orphans -= shared_memory_files_in_use()
    for name in orphans:
        for leftover in (SHM / name, SHM / f'sem.{name}_mutex'):
            leftover.unlink(missing_ok=True)
    still_there = shared_memory_identities({name for name, _ in used}) & set(used)
    holders = shared_memory_holders() if still_there else {}
    # A process that holds a port's lock file is its owner, listening, even in the moments
    # after taking the lock and before mapping the port, or after unmapping it as it closes.
    taken = {name: (holders.get(name, set()) | holders.get(f'{name}_el', set()))
             - set(graph_pids) for name, _ in still_there}
    return {name: pids for name, pids in taken.items() if pids}
