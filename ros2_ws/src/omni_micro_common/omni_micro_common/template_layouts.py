"""The layouts :class:`~omni_micro_common.cdr.MessageTemplate` finds, kept on disk between
processes. Every node builds the same few templates at start-up, and finding a layout loads
rosbags' store of message types and generates its serializers: 0.15-0.2 s of CPU per node (a
graph run that barely moves, four node processes and its orchestration, went from 5.1 s to
4.4 s of CPU). Reading one back takes about a millisecond.

A layout is filed under a digest of the message type, the fields asked for and every value the
message holds (exactly: ``repr`` of Python's numbers; not rclpy's serialized bytes, whose
padding differs from one process to the next), so a message that differs in any value has
another entry and a stale one is never read. A layout file that cannot be read, or does not
fit the fields, is found again and written anew; a folder that cannot be written only means no
layout is kept. The folder follows the XDG convention:
``$XDG_CACHE_HOME/omni-micro/cdr-templates`` (``~/.cache`` when unset); deleting it costs the
next start-up its fraction of a second, nothing else.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from pathlib import Path
from typing import Any

# Part of every digest: a new layout format files its layouts apart from the old.
LAYOUT_FORMAT = 1


def layout_folder() -> Path:
    root = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(root) / 'omni-micro' / 'cdr-templates'


def message_values(message: Any) -> list[Any]:
    """Every value of an rclpy ``message``, field by field, as plain lists of Python values."""
    values: list[Any] = []
    for name in message.get_fields_and_field_types():
        value = getattr(message, name)
        if hasattr(value, 'get_fields_and_field_types'):
            values.append(message_values(value))
        elif isinstance(value, (list, tuple)):
            values.append([message_values(item) if hasattr(item, 'get_fields_and_field_types')
                           else item for item in value])
        elif hasattr(value, 'tolist'):   # numpy's arrays and array.array
            values.append(value.tolist())
        else:
            values.append(value)
    return values


def layout_key(type_name: str, fields: dict[str, str], message: Any) -> str:
    """The digest a layout is filed under: the type, the fields (name -> kind, in order) and
    every value of ``message``."""
    record = repr((LAYOUT_FORMAT, type_name, tuple(fields.items()), message_values(message)))
    return hashlib.sha256(record.encode()).hexdigest()


def load_layout(key: str) -> tuple[bytes, tuple[int, ...]] | None:
    """The template's bytes and its fields' offsets filed under ``key``, or None when there are
    none or they cannot be read (the caller checks that they fit its fields)."""
    try:
        record = json.loads((layout_folder() / f'{key}.json').read_text())
        return bytes.fromhex(record['base']), tuple(int(offset) for offset in record['offsets'])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def store_layout(key: str, base: bytes, offsets: tuple[int, ...]) -> None:
    """File a layout under ``key``, whole or not at all (written aside, then renamed); a folder
    that cannot be written is passed over."""
    folder = layout_folder()
    temporary: str | None = None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile('w', dir=folder, prefix=f'.{key}.', suffix='.tmp',
                                         delete=False) as handle:
            temporary = handle.name
            json.dump({'base': base.hex(), 'offsets': list(offsets)}, handle)
        os.replace(temporary, folder / f'{key}.json')
        temporary = None
    except OSError:
        pass
    finally:
        if temporary is not None:
            Path(temporary).unlink(missing_ok=True)
