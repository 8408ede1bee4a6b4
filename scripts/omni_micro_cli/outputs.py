"""Writing outputs so that a failure leaves nothing half-written."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path


@contextlib.contextmanager
def staged_directory(target: Path) -> Iterator[Path]:
    """Yield a scratch directory beside ``target``; on success move its files into ``target``.

    On an exception nothing reaches ``target`` and the scratch directory is removed. Files are
    moved with ``os.replace``, so each one appears whole.
    """
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    scratch = Path(tempfile.mkdtemp(prefix=f'.{target.name}.partial-', dir=target.parent))
    try:
        yield scratch
        target.mkdir(exist_ok=True)
        for item in sorted(scratch.iterdir()):
            os.replace(item, target / item.name)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)
