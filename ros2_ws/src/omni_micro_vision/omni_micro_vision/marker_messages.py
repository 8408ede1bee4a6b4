"""The scene's shapes as a serialized visualization_msgs/MarkerArray, ready for ``publish``.

Written directly as CDR (little-endian, zeroed padding) with :mod:`struct`, not built as message
objects: markers_node shares two cores with the loop at ``--rtf max``. Building rclpy messages
took about 0.1 ms a marker; rosbags' message classes and serializer 0.38 ms for the 12-marker
array of a drawing and 7.5 ms for the whole scene; this 0.07 ms and 0.93 ms (measured on the
2-core machine). Only the fields a shape sets vary; the rest (mesh, texture, lifetime) are
constant empty values. tests/vision/test_marker_messages.py checks the bytes against rosbags'
serialization of the same array for every kind of shape and reads them back with rclpy, so the
layout cannot drift from the message definition unnoticed.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

from omni_micro_vision.scene import Shape

# visualization_msgs/Marker's type and action constants.
ARROW, CYLINDER, SPHERE_LIST, LINE_STRIP, LINE_LIST, TEXT_VIEW_FACING = 0, 3, 7, 4, 5, 9
ADD, DELETEALL = 0, 3
MARKER_TYPES = {'arrow': ARROW, 'disc': CYLINDER, 'sphere_list': SPHERE_LIST,
                'line_strip': LINE_STRIP, 'line_list': LINE_LIST, 'text': TEXT_VIEW_FACING}
MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'
# CDR, little-endian (the 4-byte encapsulation header every serialized ROS 2 message starts with).
ENCAPSULATION = b'\x00\x01\x00\x00'

_IDS = struct.Struct('<3i')                  # id, type, action
# pose (position, orientation), scale: ten float64s; color: four float32s; lifetime (sec,
# nanosec) and frame_locked: nothing between them in CDR once the first is 8-aligned.
_POSE_TO_FRAME_LOCKED = struct.Struct('<10d4fiI?')
_COUNT = struct.Struct('<I')
_EMPTY_STRING = _COUNT.pack(1) + b'\0'


def _cdr_string(text: str) -> bytes:
    encoded = text.encode()
    return _COUNT.pack(len(encoded) + 1) + encoded + b'\0'


class MarkerArrayEncoder:
    """Shapes in ``frame_id`` at a stamp -> the bytes of their MarkerArray."""

    def __init__(self, frame_id: str) -> None:
        self.frame_id = frame_id
        self._frame_id = _cdr_string(frame_id)
        self._strings: dict[str, bytes] = {}       # namespaces and texts, encoded once

    def encode(self, shapes: Sequence[Shape], stamp: tuple[int, int],
               clear_first: bool = False) -> bytes:
        """The MarkerArray of ``shapes`` stamped ``(sec, nanosec)``; with ``clear_first`` a
        DELETEALL marker leads, so that a viewer drops what it drew before."""
        buffer = bytearray(ENCAPSULATION)
        buffer += _COUNT.pack(len(shapes) + (1 if clear_first else 0))
        header = struct.pack('<iI', *stamp) + self._frame_id
        if clear_first:
            self._marker(buffer, header, '', 0, ARROW, DELETEALL, 0.0, 0.0, (0.0, 0.0, 0.0),
                         (0.0, 0.0, 0.0, 0.0), (), '')
        for shape in shapes:
            self._shape(buffer, header, shape)
        return bytes(buffer)

    def _shape(self, buffer: bytearray, header: bytes, shape: Shape) -> None:
        size = shape.size_m
        x = y = 0.0
        points: Sequence[tuple[float, float]] = ()
        text = ''
        if shape.kind in ('disc', 'text'):
            x, y = shape.points[0]
            if shape.kind == 'disc':
                scale = (size, size, size * 0.02)
            else:
                scale, text = (0.0, 0.0, size), shape.text
        else:
            points = shape.points
            if shape.kind == 'arrow':
                # Shaft diameter, head diameter, head length (RViz's and Foxglove's convention).
                length = math.dist(*shape.points)
                scale = (size, 2.0 * size, min(4.0 * size, 0.3 * length) if length > 0 else 0.0)
            elif shape.kind == 'sphere_list':
                scale = (size, size, size)
            else:
                scale = (size, 0.0, 0.0)
        self._marker(buffer, header, shape.namespace, shape.id, MARKER_TYPES[shape.kind], ADD,
                     x, y, scale, shape.colour, points, text)

    def _string(self, text: str) -> bytes:
        encoded = self._strings.get(text)
        if encoded is None:
            encoded = self._strings[text] = _cdr_string(text)
        return encoded

    def _marker(self, buffer: bytearray, header: bytes, namespace: str, marker_id: int,
                kind: int, action: int, x: float, y: float,
                scale: tuple[float, float, float], colour: tuple[float, float, float, float],
                points: Sequence[tuple[float, float]], text: str) -> None:
        # Field by field as visualization_msgs/msg/Marker declares them; each value aligned to
        # its own size, counted from after the encapsulation header.
        _align(buffer, 4)
        buffer += header                                   # stamp, frame_id
        _align(buffer, 4)
        buffer += self._string(namespace)
        _align(buffer, 4)
        buffer += _IDS.pack(marker_id, kind, action)
        _align(buffer, 8)
        buffer += _POSE_TO_FRAME_LOCKED.pack(x, y, 0.0, 0.0, 0.0, 0.0, 1.0, *scale, *colour,
                                             0, 0, False)
        _align(buffer, 4)
        buffer += _COUNT.pack(len(points))
        if points:
            _align(buffer, 8)
            buffer += struct.pack(f'<{3 * len(points)}d',
                                  *(value for x_y in points for value in (*x_y, 0.0)))
        _align(buffer, 4)
        buffer += _EMPTY_TAIL_BEFORE_TEXT
        buffer += self._string(text)
        _align(buffer, 4)
        buffer += _EMPTY_TAIL_AFTER_TEXT


def _align(buffer: bytearray, size: int) -> None:
    padding = -(len(buffer) - len(ENCAPSULATION)) % size
    if padding:
        buffer += bytes(padding)


# From colors to uv_coordinates, every field empty and each 4-aligned where the last ends:
# colors (count 0), texture_resource '', texture (header: stamp 0, frame_id ''; format ''; data
# count 0), uv_coordinates (count 0).
_EMPTY_TAIL_BEFORE_TEXT = b''.join((
    _COUNT.pack(0), _EMPTY_STRING, b'\0\0\0',
    struct.pack('<iI', 0, 0), _EMPTY_STRING, b'\0\0\0', _EMPTY_STRING, b'\0\0\0',
    _COUNT.pack(0), _COUNT.pack(0)))
# After text: mesh_resource '', mesh_file (filename '', data count 0),
# mesh_use_embedded_materials False.
_EMPTY_TAIL_AFTER_TEXT = b''.join((_EMPTY_STRING, b'\0\0\0', _EMPTY_STRING, b'\0\0\0',
                                   _COUNT.pack(0), b'\0'))
