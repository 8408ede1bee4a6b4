"""Message classes by their type name (rosidl_runtime_py, which does this, is not a wheel)."""

from __future__ import annotations

import importlib


def message_class(msgtype: str) -> type:
    """The rclpy message class of ``'pkg/msg/Name'``.

    Raises
    ------
    ValueError
        ``msgtype`` is not of the form pkg/msg/Name, or no such message is installed.
    """
    parts = msgtype.split('/')
    if len(parts) != 3 or parts[1] != 'msg' or not all(parts):
        raise ValueError(f'expected a message type pkg/msg/Name, got {msgtype!r}')
    package, _, name = parts
    try:
        return getattr(importlib.import_module(f'{package}.msg'), name)  # type: ignore[no-any-return]
    except (ImportError, AttributeError):
        raise ValueError(f'message type {msgtype!r} is not installed') from None
