"""Messages serialized once and patched in place: the per-tick streams without rclpy's
Python-to-C message conversion.

A :class:`MessageTemplate` serializes a message once (its strings, its array lengths and every
field it is not told about stay as they were) and finds, by probing, where in the CDR bytes each
named number lives; :meth:`MessageTemplate.encode` writes new numbers there and hands the bytes
to ``publish`` (rclpy publishes ``bytes`` as they are), :meth:`MessageTemplate.decode` reads them
back from a raw subscription. The bytes are those a publisher of the same message sends (tested),
so every subscriber, the recorder and ``ros2 topic echo`` see ordinary messages.

The template's bytes come from rosbags' serializer, not from rclpy's ``serialize_message``:
that one leaves whatever was in memory in the alignment padding (and pads the end), so the same
message would not give the same bytes in two runs, and a bag would not be the same bag. What a
template finds is kept on disk (:mod:`omni_micro_common.template_layouts`): the next process
that builds the same one reads it back instead of loading rosbags.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any, Literal

from rclpy.serialization import deserialize_message

from omni_micro_common.template_layouts import layout_key, load_layout, store_layout

# rclpy's type names of the numbers a message may hold in an array, as numpy dtypes (numpy and
# rosbags load only when a template's layout must be found: node_runtime imports this module,
# and the shared contracts load nothing heavy).
_DTYPES = {'double': 'float64', 'float': 'float32', 'int8': 'int8', 'uint8': 'uint8',
           'int16': 'int16', 'uint16': 'uint16', 'int32': 'int32', 'uint32': 'uint32',
           'int64': 'int64', 'uint64': 'uint64', 'octet': 'uint8', 'boolean': 'bool'}

# The kinds of number a template can patch, as struct formats (CDR little-endian: the rmw's
# encapsulation header says so; a template refuses a big-endian one).
KINDS = {'float64': 'd', 'int32': 'i', 'uint32': 'I'}
LITTLE_ENDIAN_CDR = (b'\x00\x01', b'\x00\x03')   # CDR_LE, PL_CDR_LE


def typestore() -> Any:
    """rosbags' store of Jazzy's message types (loaded on first use: rosbags is not light)."""
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def _type_name(message: Any) -> str:
    return f'{type(message).__module__.split(".")[0]}/msg/{type(message).__name__}'


def _element_type(field_type: str) -> str:
    """'sequence<double>', 'double[36]', 'sequence<double, 3>' -> 'double'."""
    if field_type.startswith('sequence<'):
        return field_type[len('sequence<'):].split(',')[0].rstrip('>').strip()
    return field_type.split('[')[0]


def _as_rosbags(message: Any, store: Any) -> Any:
    """The same message as rosbags' dataclass, field by field."""
    import numpy as np

    values: dict[str, Any] = {}
    for name, field_type in message.get_fields_and_field_types().items():
        value = getattr(message, name)
        element = _element_type(field_type)
        if hasattr(value, 'get_fields_and_field_types'):
            values[name] = _as_rosbags(value, store)
        elif element != field_type and element in _DTYPES:
            values[name] = np.asarray(value, dtype=_DTYPES[element])
        elif isinstance(value, (list, tuple)):
            values[name] = [_as_rosbags(item, store)
                            if hasattr(item, 'get_fields_and_field_types') else item
                            for item in value]
        elif isinstance(value, bytes) and len(value) == 1:
            values[name] = value[0]   # rclpy's byte is a bytes of one; rosbags' an int
        else:
            values[name] = value
    return store.types[_type_name(message)](**values)


def canonical_bytes(message: Any, store: Any | None = None) -> bytes:
    """``message`` serialized as a publisher sends it: CDR, zeros in the padding."""
    store = store or typestore()
    return bytes(store.serialize_cdr(_as_rosbags(message, store), _type_name(message)))


def _get(message: Any, path: Sequence[str | int]) -> Any:
    for step in path:
        message = message[step] if isinstance(step, int) else getattr(message, step)
    return message


def _set(message: Any, path: Sequence[str | int], value: Any) -> None:
    parent = _get(message, path[:-1])
    last = path[-1]
    if isinstance(last, int):
        parent[last] = value
    else:
        setattr(parent, last, value)


def _path(name: str) -> tuple[str | int, ...]:
    """'pose.pose.position.x' or 'position[2]' as the steps to the field."""
    steps: list[str | int] = []
    for part in name.split('.'):
        if part.endswith(']'):
            field, index = part[:-1].split('[')
            steps += [field, int(index)]
        else:
            steps.append(part)
    return tuple(steps)


def _find_layout(message: Any, fields: dict[str, str]) -> tuple[bytes, tuple[int, ...]]:
    """``message``'s canonical bytes and where each of ``fields`` lies in them, found by writing
    a value no other field holds into each in turn (see :class:`MessageTemplate`)."""
    message_type = type(message).__name__
    store = typestore()
    base = canonical_bytes(message, store)
    if base[:2] not in LITTLE_ENDIAN_CDR:
        raise ValueError(f'{message_type}: not little-endian CDR')
    offsets = []
    for index, (name, kind) in enumerate(fields.items()):
        path = _path(name)
        original = _get(message, path)
        probe: float | int = 1.0e300 / (index + 3) if kind == 'float64' else 0x5A5A0000 + index
        _set(message, path, probe)
        probed = canonical_bytes(message, store)
        _set(message, path, original)
        pattern = struct.pack('<' + KINDS[kind], probe)
        where = probed.find(pattern)
        if where < 0 or probed.find(pattern, where + 1) >= 0 or len(probed) != len(base):
            raise ValueError(f'{message_type}.{name}: not found alone in the serialized message')
        offsets.append(where)
    return base, tuple(offsets)


class MessageTemplate:
    """``message`` serialized once, with the offsets of ``fields`` (name -> kind of number).

    Field names are attribute paths, with ``[k]`` for an element of an array:
    ``'header.stamp.sec'``, ``'pose.pose.position.x'``, ``'position[1]'``.

    Raises
    ------
    ValueError
        If a field cannot be found alone in the bytes (it would be patched wrongly).
    """

    def __init__(self, message: Any, fields: dict[str, str]) -> None:
        self.message_type = type(message)
        self.names = tuple(fields)
        self._packers = [struct.Struct('<' + KINDS[kind]) for kind in fields.values()]
        # Finding the layout costs a node 0.15-0.2 s of CPU; one found before is read back.
        key = layout_key(_type_name(message), fields, message)
        layout = load_layout(key)
        if layout is None or not self._fits(*layout):
            layout = _find_layout(message, fields)
            store_layout(key, *layout)
        base, offsets = layout
        self._base = base
        self._offsets = offsets
        # The bytes between the patched numbers: a message whose bytes there are the
        # template's has its numbers where the template has them.
        spans = sorted((offset, offset + packer.size)
                       for offset, packer in zip(offsets, self._packers, strict=True))
        edges = [0, *(edge for span in spans for edge in span), len(base)]
        self._static = [(start, end) for start, end in zip(edges[::2], edges[1::2], strict=True)
                        if end > start]

    def _fits(self, base: bytes, offsets: tuple[int, ...]) -> bool:
        """Whether a layout read back holds this template's fields, each within the bytes."""
        return (base[:2] in LITTLE_ENDIAN_CDR and len(offsets) == len(self._packers)
                and all(offset > 0 and offset + packer.size <= len(base)
                        for offset, packer in zip(offsets, self._packers, strict=True)))

    def encode(self, values: Sequence[float | int]) -> bytes:
        """The message with ``values`` (in the order of ``fields``) written in."""
        buffer = bytearray(self._base)
        for packer, offset, value in zip(self._packers, self._offsets, values, strict=True):
            packer.pack_into(buffer, offset, value)
        return bytes(buffer)

    def matches(self, data: bytes) -> bool:
        """Whether ``data`` is this template with other numbers in its fields (so that
        :meth:`decode` reads the right bytes): same length, same bytes everywhere else."""
        base = self._base
        return len(data) == len(base) and all(data[start:end] == base[start:end]
                                              for start, end in self._static)

    def read(self, data: bytes) -> tuple[float | int, ...] | None:
        """The ``fields`` of ``data`` if it has this template's layout (:meth:`matches`), else
        None."""
        if not self.matches(data):
            return None
        return tuple(packer.unpack_from(data, offset)[0]
                     for packer, offset in zip(self._packers, self._offsets, strict=True))

    def decode(self, data: bytes) -> tuple[float | int, ...]:
        """The ``fields`` of ``data``: read in place with this template's layout, else (a
        message from another publisher) deserialized in full, then read by name."""
        values = self.read(data)
        if values is not None:
            return values
        message = deserialize_message(data, self.message_type)
        return tuple(_get(message, _path(name)) for name in self.names)


# diagnostic_msgs/DiagnosticStatus by hand: the lockstep reports are strings of varying length,
# so no template fits them; this is the same CDR, a few microseconds instead of a message built
# and converted per report.
_ENCAPSULATION = b'\x00\x01\x00\x00'


def _string(parts: list[bytes], size: int, text: str) -> int:
    """Append a CDR string (4-aligned length, bytes, NUL) at ``size``; return the new size."""
    pad = -size % 4
    encoded = text.encode()
    parts.append(b'\x00' * pad + struct.pack('<I', len(encoded) + 1) + encoded + b'\x00')
    return size + pad + 4 + len(encoded) + 1


def diagnostic_status_bytes(level: int, name: str, message: str, hardware_id: str,
                            values: Sequence[tuple[str, str]]) -> bytes:
    """A diagnostic_msgs/DiagnosticStatus serialized as a publisher sends it."""
    parts = [struct.pack('<B', level)]
    size = 1   # the payload's own offsets count from after the encapsulation header
    for text in (name, message, hardware_id):
        size = _string(parts, size, text)
    pad = -size % 4
    parts.append(b'\x00' * pad + struct.pack('<I', len(values)))
    size += pad + 4
    for key, value in values:
        size = _string(parts, size, key)
        size = _string(parts, size, value)
    return _ENCAPSULATION + b''.join(parts)


def read_string(data: bytes | memoryview, offset: int) -> tuple[str, int]:
    """The CDR string at payload ``offset`` (counted from after the encapsulation header, then
    aligned to 4) and the offset after it.

    Raises
    ------
    struct.error, UnicodeDecodeError
        If the bytes end before the string, or it is not UTF-8.
    """
    offset += -offset % 4
    (length,) = struct.unpack_from('<I', data, 4 + offset)
    start = 4 + offset + 4
    return bytes(data[start:start + length - 1]).decode(), offset + 4 + length


def read_diagnostic_status(data: bytes) -> tuple[int, str, str, str, list[tuple[str, str]]]:
    """(level, name, message, hardware_id, values) of a serialized DiagnosticStatus.

    Raises
    ------
    ValueError, IndexError, struct.error
        If the bytes are not a little-endian DiagnosticStatus.
    """
    if data[:2] not in LITTLE_ENDIAN_CDR:
        raise ValueError('not little-endian CDR')
    level = data[4]
    offset = 1
    texts = []
    for _ in range(3):
        text, offset = read_string(data, offset)
        texts.append(text)
    offset += -offset % 4
    (count,) = struct.unpack_from('<I', data, 4 + offset)
    offset += 4
    values = []
    for _ in range(count):
        key, offset = read_string(data, offset)
        value, offset = read_string(data, offset)
        values.append((key, value))
    return level, texts[0], texts[1], texts[2], values


def header_stamp_ns(data: bytes) -> int:
    """The header stamp of a serialized message that starts with a std_msgs/Header, without
    decoding the rest: CDR puts a 4-byte encapsulation, then stamp.sec and stamp.nanosec."""
    order: Literal['little', 'big'] = 'little' if data[1] & 1 else 'big'
    return (int.from_bytes(data[4:8], order, signed=True) * 1_000_000_000
            + int.from_bytes(data[8:12], order))
