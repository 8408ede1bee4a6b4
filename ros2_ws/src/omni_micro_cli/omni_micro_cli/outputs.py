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


def atomic_text(target: Path, text: str) -> None:
    """Write ``text`` to ``target`` whole or not at all (a temporary file, then a rename)."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f'.{target.name}.partial-', dir=target.parent)
    try:
        with os.fdopen(handle, 'w') as stream:
            stream.write(text)
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise
