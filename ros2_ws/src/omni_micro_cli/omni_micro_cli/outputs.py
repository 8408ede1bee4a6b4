"""Outputs: checked before anything runs, and written so that a failure leaves nothing
half-written."""

from __future__ import annotations

import argparse
import contextlib
import csv
import io
import json
import os
import shutil
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator, Sequence
from pathlib import Path
from typing import TextIO

# Where print_json writes: the real standard output while a --json command runs with everything
# else it prints sent to standard error (json_alone_on_stdout).
_json_stream: TextIO | None = None


@contextlib.contextmanager
def json_alone_on_stdout() -> Iterator[None]:
    """With ``--json``, standard output is the JSON document alone (``omni-micro fleet --json |
    jq`` works): what the command prints otherwise, tables and progress, goes to standard
    error."""
    global _json_stream
    _json_stream = sys.stdout
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        _json_stream = None


def print_json(value: object) -> None:
    """``value`` as one JSON line on standard output (the real one under json_alone_on_stdout)."""
    print(json.dumps(value), file=_json_stream or sys.stdout, flush=True)


def output_problem(path: Path, kind: str) -> str | None:
    """What stops ``path`` from being written as a ``kind`` ('folder' or 'file'), or None.

    Nothing is created: the nearest existing folder on the way must be a folder we may write.
    """
    try:
        return _output_problem(path, kind)
    except OSError as error:   # a name too long for the file system, a loop of links
        return f'cannot be used: {error.strerror or error}'


def _output_problem(path: Path, kind: str) -> str | None:
    if os.path.lexists(path) and not path.exists():
        return 'is a symbolic link to nothing (broken, or a loop of links)'
    if path.exists():
        if kind == 'folder' and not path.is_dir():
            return 'exists and is a file (expected a folder)'
        if kind == 'file' and path.is_dir():
            return 'is a folder (expected a file)'
    ancestor = path if kind == 'folder' and path.is_dir() else path.parent
    while not ancestor.exists() and ancestor != ancestor.parent:
        ancestor = ancestor.parent
    if not ancestor.is_dir():
        return f'is under {str(ancestor)!r}, which is a file'
    if not os.access(ancestor, os.W_OK | os.X_OK):
        return f'cannot be written: {str(ancestor)!r} is not writable (read-only or no permission)'
    return None


def _output(kind: str) -> Callable[[str], Path]:
    def parse(text: str) -> Path:
        path = Path(text)
        problem = output_problem(path, kind)
        if problem:
            raise argparse.ArgumentTypeError(f'{text!r} {problem}')
        return path
    parse.__name__ = f'output_{kind}'
    return parse


# argparse types of every output path: a path that cannot be written is refused, naming it and
# the problem, before anything runs (exit 2).
output_folder = _output('folder')
output_file = _output('file')


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
    atomic_bytes(target, text.encode())


def atomic_bytes(target: Path, data: bytes) -> None:
    """Write ``data`` to ``target`` whole or not at all (a temporary file, then a rename)."""
    target = Path(target)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f'.{target.name}.partial-', dir=target.parent)
    try:
        with os.fdopen(handle, 'wb') as stream:
            stream.write(data)
        # mkstemp makes the file private (0600): give it the mode a plain open() would.
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def echo_to_stderr(line: str) -> None:
    print(line, file=sys.stderr, flush=True)


def atomic_csv(target: Path, header: list[str], rows: Iterable[Sequence[object]]) -> None:
    """A CSV table written whole or not at all (atomic_text)."""
    table = io.StringIO()
    writer = csv.writer(table)
    writer.writerow(header)
    writer.writerows(rows)
    atomic_text(target, table.getvalue())
