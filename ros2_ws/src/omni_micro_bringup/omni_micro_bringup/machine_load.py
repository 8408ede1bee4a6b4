"""Other programs keeping the machine's cores busy, as on a shared CI host: for the benchmark
and for the tests that show a busy machine slows a run down but never changes it."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Callable, Iterator

# Spins one core until killed, and stops by itself if its parent dies: it never outlives us.
_HOG = 'import os\nparent = os.getppid()\nwhile os.getppid() == parent:\n    pass\n'


@contextlib.contextmanager
def busy_cores(count: int, on_done: Callable[[float], None] | None = None) -> Iterator[
        list[subprocess.Popen[bytes]]]:
    """Run the block with ``count`` cores kept busy (the block gets the busy processes);
    ``on_done`` is told the CPU seconds they used (what a measure of the block's own CPU leaves
    out)."""
    hogs = [subprocess.Popen([sys.executable, '-c', _HOG]) for _ in range(count)]
    used_s = 0.0
    try:
        yield hogs
    finally:
        for hog in hogs:
            hog.kill()
            _, status, usage = os.wait4(hog.pid, 0)
            hog.returncode = os.waitstatus_to_exitcode(status)
            used_s += usage.ru_utime + usage.ru_stime
        if on_done is not None:
            on_done(used_s)
