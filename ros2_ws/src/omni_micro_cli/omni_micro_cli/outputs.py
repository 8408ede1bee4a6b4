"""Writing outputs so that a failure leaves nothing half-written."""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

from omni_micro_cli.errors import UsageError


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


def check_output_path(path: Path, force: bool) -> None:
    """Refuse to overwrite, unless ``force`` and the path is a bag (never an arbitrary folder)."""
    if not path.exists():
        # Made here, as demo does: a newcomer's `--record out/bags/mine` should just work.
        path.parent.mkdir(parents=True, exist_ok=True)
        return
    if not force:
        raise UsageError(f'{str(path)!r} exists already; give --force to replace it')
    looks_like_bag = path.is_dir() and all(
        child.name == 'metadata.yaml' or child.suffix in ('.mcap', '.db3')
        for child in path.iterdir())
    if not looks_like_bag:
        raise UsageError(f'{str(path)!r} exists and is not a bag; not replacing it even with '
                         f'--force')
    shutil.rmtree(path)
