"""Fast DDS shared-memory files in /dev/shm: who holds them, and what a killed process left."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

SHM = Path('/dev/shm')


def shared_memory_files() -> set[str]:
    return {path.name for path in SHM.glob('*fastrtps*')} if SHM.is_dir() else set()


def shared_memory_files_in_use(pids: list[int] | None = None) -> set[str]:
    """The Fast DDS shared-memory files some living process (of ``pids``: any this user may
    read) maps (its segments and ports) or holds open (their ``_el`` lock files)."""
    in_use: set[str] = set()
    processes = (Path('/proc').glob('[0-9]*') if pids is None
                 else [Path(f'/proc/{pid}') for pid in pids])
    for process in processes:
        try:
            in_use.update(line.rsplit('/', 1)[-1]
                          for line in (process / 'maps').read_text().splitlines()
                          if '/dev/shm/fastrtps' in line)
            for fd in (process / 'fd').iterdir():
                target = os.readlink(fd)
                if target.startswith('/dev/shm/fastrtps'):
                    in_use.add(target.rsplit('/', 1)[-1])
        except OSError:   # the process ended while we looked, or is not ours to read
            continue
    return in_use


def left_shared_memory(codes: dict[str, int | None], starts: list[int]) -> bool:
    """Whether a graph's processes may have left shared-memory files: one did not stop on its
    signal with code 0 (killed, crashed, stuck), or one was started again after dying."""
    return any(code != 0 for code in codes.values()) or any(count > 1 for count in starts)


def clean_shared_memory() -> None:
    """Remove the Fast DDS shared-memory files a killed process left behind.

    `fastdds shm clean` removes segments and ports whose owner died (a SIGKILL leaves them).
    It leaves port files with no `_el` lock file: nobody listens on those any more, yet they
    stay in /dev/shm. Those are removed too when no process maps them (a writer that opened a
    port before its reader still does), whoever made them: every participant takes the first
    free of fastrtps_port7000, 7001, ... whatever its domain, so a port one run's killed
    process left is the next one's, of any run, and a process killed there leaves it again
    under a name the second run had not made.
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
