"""The scene's shapes as a serialized visualization_msgs/MarkerArray, ready for ``publish``.

Built from rosbags' message classes and serialized by rosbags' CDR serializer rather than as
rclpy messages: rclpy's conversion of a Python MarkerArray to C was most of markers_node's time
(about 0.1 ms a marker, measured), and markers_node shares two cores with the loop at
``--rtf max``; rosbags builds and serializes a 12-marker array in 0.27 ms. The bytes
are an ordinary CDR MarkerArray (tests/vision/test_marker_messages.py reads them back with
rclpy), with zeroed padding, so that the same shapes always give the same bytes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from omni_micro_common.cdr import typestore
from omni_micro_vision.scene import Shape

# visualization_msgs/Marker's type and action constants.
ARROW, CYLINDER, SPHERE_LIST, LINE_STRIP, LINE_LIST, TEXT_VIEW_FACING = 0, 3, 7, 4, 5, 9
ADD, DELETEALL = 0, 3
MARKER_TYPES = {'arrow': ARROW, 'disc': CYLINDER, 'sphere_list': SPHERE_LIST,
                'line_strip': LINE_STRIP, 'line_list': LINE_LIST, 'text': TEXT_VIEW_FACING}
MARKER_ARRAY = 'visualization_msgs/msg/MarkerArray'


class MarkerArrayEncoder:
    """Shapes in ``frame_id`` at a stamp -> the bytes of their MarkerArray."""

    def __init__(self, frame_id: str) -> None:
        import numpy as np

        self._store = typestore()
        types = self._store.types
        self._marker_type = types['visualization_msgs/msg/Marker']
        self._array = types[MARKER_ARRAY]
        self._header = types['std_msgs/msg/Header']
        self._time = types['builtin_interfaces/msg/Time']
        self._pose = types['geometry_msgs/msg/Pose']
        self._point = types['geometry_msgs/msg/Point']
        self._quaternion = types['geometry_msgs/msg/Quaternion']
        self._vector = types['geometry_msgs/msg/Vector3']
        self._colour = types['std_msgs/msg/ColorRGBA']
        self.frame_id = frame_id
        # The fields no shape uses, shared by every marker (serializing only reads them).
        empty = np.zeros(0, np.uint8)
        self._unused: dict[str, Any] = {
            'lifetime': types['builtin_interfaces/msg/Duration'](sec=0, nanosec=0),
            'frame_locked': False, 'colors': [], 'texture_resource': '',
            'texture': types['sensor_msgs/msg/CompressedImage'](
                header=self._header(stamp=self._time(sec=0, nanosec=0), frame_id=''),
                format='', data=empty),
            'uv_coordinates': [], 'mesh_resource': '',
            'mesh_file': types['visualization_msgs/msg/MeshFile'](filename='', data=empty),
            'mesh_use_embedded_materials': False}
        self._identity = self._quaternion(x=0.0, y=0.0, z=0.0, w=1.0)
        self._origin = self._point(x=0.0, y=0.0, z=0.0)
        # rosbags writes each type's serializer on first use (0.1-0.2 s): at start-up, not in
        # the first array of a run.
        self.encode([Shape('', 0, 'line_strip', ((0.0, 0.0), (1.0, 0.0)), (0, 0, 0, 0), 1.0)],
                    (0, 0), clear_first=True)

    def encode(self, shapes: Sequence[Shape], stamp: tuple[int, int],
               clear_first: bool = False) -> bytes:
        """The MarkerArray of ``shapes`` stamped ``(sec, nanosec)``; with ``clear_first`` a
        DELETEALL marker leads, so that a viewer drops what it drew before."""
        header = self._header(stamp=self._time(sec=stamp[0], nanosec=stamp[1]),
                              frame_id=self.frame_id)
        markers = [self._marker(header, '', 0, ARROW, DELETEALL, self._origin, (0.0, 0.0, 0.0),
                                (0.0, 0.0, 0.0, 0.0))] if clear_first else []
        markers += [self._marker_of(shape, header) for shape in shapes]
        return bytes(self._store.serialize_cdr(self._array(markers=markers), MARKER_ARRAY))

    def _marker_of(self, shape: Shape, header: Any) -> Any:
        size = shape.size_m
        position = self._origin
        points: list[Any] = []
        text = ''
        if shape.kind in ('disc', 'text'):
            x, y = shape.points[0]
            position = self._point(x=x, y=y, z=0.0)
            if shape.kind == 'disc':
                scale = (size, size, size * 0.02)
            else:
                scale, text = (0.0, 0.0, size), shape.text
        else:
            points = [self._point(x=x, y=y, z=0.0) for x, y in shape.points]
            if shape.kind == 'arrow':
                # Shaft diameter, head diameter, head length (RViz's and Foxglove's convention).
                length = math.dist(*shape.points)
                scale = (size, 2.0 * size, min(4.0 * size, 0.3 * length) if length > 0 else 0.0)
            elif shape.kind == 'sphere_list':
                scale = (size, size, size)
            else:
                scale = (size, 0.0, 0.0)
        return self._marker(header, shape.namespace, shape.id, MARKER_TYPES[shape.kind], ADD,
                            position, scale, shape.colour, points, text)

    def _marker(self, header: Any, namespace: str, marker_id: int, kind: int, action: int,
                position: Any, scale: tuple[float, float, float],
                colour: tuple[float, float, float, float], points: list[Any] | None = None,
                text: str = '') -> Any:
        r, g, b, a = colour
        return self._marker_type(
            header=header, ns=namespace, id=marker_id, type=kind, action=action,
            pose=self._pose(position=position, orientation=self._identity),
            scale=self._vector(x=scale[0], y=scale[1], z=scale[2]),
            color=self._colour(r=r, g=g, b=b, a=a), points=points or [], text=text,
            **self._unused)
