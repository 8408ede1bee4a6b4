"""Other programs keeping the machine's cores busy, as on a shared CI host: for the benchmark
and for the tests that show a busy machine slows a run down but never changes it."""

from __future__ import annotations

import contextlib
import subprocess
import sys
from collections.abc import Iterator

# Spins one core until killed, and stops by itself if its parent dies: it never outlives us.
_HOG = 'import os\nparent = os.getppid()\nwhile os.getppid() == parent:\n    pass\n'


@contextlib.contextmanager
def busy_cores(count: int) -> Iterator[None]:
    """Run the block with ``count`` cores kept busy."""
    hogs = [subprocess.Popen([sys.executable, '-c', _HOG]) for _ in range(count)]
    try:
        yield
    finally:
        for hog in hogs:
            hog.kill()
            hog.wait()
