"""What a piece of code loads, looked at in a fresh interpreter (an import, unlike a time, does
not flake)."""

from __future__ import annotations

import json
import subprocess
import sys

# Libraries that take a noticeable time to import.
HEAVY = ('numba', 'llvmlite', 'scipy', 'matplotlib', 'pyarrow', 'dask', 'distributed', 'cv2',
         'rosbags', 'rclpy')


def loaded_after(code: str, watched: tuple[str, ...]) -> list[str]:
    probe = (f'import sys, json\n{code}\n'
             f'print(json.dumps(sorted(m for m in {watched!r} if m in sys.modules)))')
    done = subprocess.run([sys.executable, '-c', probe], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    return list(json.loads(done.stdout.strip().splitlines()[-1]))
