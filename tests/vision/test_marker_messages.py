"""The markers' wire format (omni_micro_vision.marker_messages): the bytes markers_node
publishes are rosbags' serialization of the same MarkerArray, byte for byte, and read back with
rclpy's own deserializer as the MarkerArray of the scene's shapes."""

import math

import pytest
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import Marker, MarkerArray

from omni_micro_common.cdr import typestore
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.marker_messages import MARKER_ARRAY, MARKER_TYPES, MarkerArrayEncoder
from omni_micro_vision.scene import CAPTURE_LIST_POINTS, Scene

KINDS = {'arrow': Marker.ARROW, 'disc': Marker.CYLINDER, 'sphere_list': Marker.SPHERE_LIST,
         'line_strip': Marker.LINE_STRIP, 'line_list': Marker.LINE_LIST,
         'text': Marker.TEXT_VIEW_FACING}


def a_scene_with_everything() -> Scene:
    scene = Scene(DEFAULT_RIG)
    scene.on_goal(0.1, 0.0)
    for step in range(80):
        scene.on_odometry(step * 1.2e-3, 1e-5 * step, 0.01 * step)
        scene.on_capture('macro', step * 1.2e-3, 0.0)
        scene.on_capture_uncertainty('macro', step * 1.2e-3, 0.0, 2e-5)
    scene.on_steering(0.3)
    scene.on_slip((1e-4, 0.0, -2e-4), (3e-5, 0.0, 0.0))
    scene.on_move(0.1, 5e-3)
    return scene


def test_every_shape_reads_back_as_the_marker_a_viewer_expects():
    scene = a_scene_with_everything()
    shapes = scene.robot_shapes() + scene.route_shapes(only_last=False) + scene.static_shapes()
    assert {shape.kind for shape in shapes} == set(KINDS)       # every kind is tried
    data = MarkerArrayEncoder('platform').encode(shapes, (12, 340_000_000))
    markers = deserialize_message(data, MarkerArray).markers
    assert len(markers) == len(shapes)
    for shape, marker in zip(shapes, markers, strict=True):
        assert (marker.ns, marker.id, marker.type) == (shape.namespace, shape.id,
                                                      KINDS[shape.kind])
        assert marker.action == Marker.ADD and marker.header.frame_id == 'platform'
        assert (marker.header.stamp.sec, marker.header.stamp.nanosec) == (12, 340_000_000)
        assert tuple(getattr(marker.color, c) for c in 'rgba') == \
            pytest.approx(shape.colour, abs=1e-7)      # ColorRGBA is float32
        assert marker.pose.orientation.w == 1.0
        if shape.kind in ('disc', 'text'):
            assert (marker.pose.position.x, marker.pose.position.y) == shape.points[0]
            assert not marker.points
            assert marker.text == shape.text
            expected_scale = ((shape.size_m, shape.size_m, 0.02 * shape.size_m)
                              if shape.kind == 'disc' else (0.0, 0.0, shape.size_m))
        else:
            assert [(p.x, p.y, p.z) for p in marker.points] == \
                [(x, y, 0.0) for x, y in shape.points]
            if shape.kind == 'arrow':
                length = math.dist(*shape.points)
                expected_scale = (shape.size_m, 2 * shape.size_m,
                                  min(4 * shape.size_m, 0.3 * length))
            elif shape.kind == 'sphere_list':
                expected_scale = (shape.size_m,) * 3
            else:
                expected_scale = (shape.size_m, 0.0, 0.0)
        assert (marker.scale.x, marker.scale.y, marker.scale.z) == \
            pytest.approx(expected_scale, rel=1e-12)


def test_a_cleared_scene_leads_with_delete_all_and_the_same_shapes_give_the_same_bytes():
    scene = a_scene_with_everything()
    encoder = MarkerArrayEncoder('platform')
    shapes = scene.robot_shapes()
    data = encoder.encode(shapes, (3, 0), clear_first=True)
    first, *rest = deserialize_message(data, MarkerArray).markers
    assert first.action == Marker.DELETEALL and first.header.frame_id == 'platform'
    assert [marker.ns for marker in rest] == [shape.namespace for shape in shapes]
    assert encoder.encode(shapes, (3, 0), clear_first=True) == data


def test_a_new_capture_resends_only_the_last_list_of_captures():
    scene = a_scene_with_everything()
    newest = [shape for shape in scene.static_shapes(frozenset({'captures'}), newest_only=True)
              if shape.namespace == 'captures/macro']
    assert [shape.id for shape in newest] == [80 // CAPTURE_LIST_POINTS]
    assert len(newest[0].points) == 80 % CAPTURE_LIST_POINTS
    every = [shape for shape in scene.static_shapes() if shape.namespace == 'captures/macro']
    assert sum(len(shape.points) for shape in every) == 80


def rosbags_marker_array(shapes, stamp, frame_id: str, clear_first: bool) -> bytes:
    """The same MarkerArray built from rosbags' message classes and serialized by rosbags."""
    import numpy as np

    store = typestore()
    types = store.types
    time_of = types['builtin_interfaces/msg/Time']
    header_of = types['std_msgs/msg/Header']
    point = types['geometry_msgs/msg/Point']
    empty = np.zeros(0, np.uint8)

    def marker(namespace, marker_id, kind, action, position, scale, colour, points, text):
        return types['visualization_msgs/msg/Marker'](
            header=header_of(stamp=time_of(sec=stamp[0], nanosec=stamp[1]), frame_id=frame_id),
            ns=namespace, id=marker_id, type=kind, action=action,
            pose=types['geometry_msgs/msg/Pose'](
                position=point(x=position[0], y=position[1], z=0.0),
                orientation=types['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)),
            scale=types['geometry_msgs/msg/Vector3'](x=scale[0], y=scale[1], z=scale[2]),
            color=types['std_msgs/msg/ColorRGBA'](r=colour[0], g=colour[1], b=colour[2],
                                                  a=colour[3]),
            lifetime=types['builtin_interfaces/msg/Duration'](sec=0, nanosec=0),
            frame_locked=False, points=[point(x=x, y=y, z=0.0) for x, y in points], colors=[],
            texture_resource='', texture=types['sensor_msgs/msg/CompressedImage'](
                header=header_of(stamp=time_of(sec=0, nanosec=0), frame_id=''), format='',
                data=empty),
            uv_coordinates=[], text=text, mesh_resource='',
            mesh_file=types['visualization_msgs/msg/MeshFile'](filename='', data=empty),
            mesh_use_embedded_materials=False)

    markers = [marker('', 0, Marker.ARROW, Marker.DELETEALL, (0.0, 0.0), (0.0, 0.0, 0.0),
                      (0.0, 0.0, 0.0, 0.0), (), '')] if clear_first else []
    for shape in shapes:
        decoded = deserialize_message(MarkerArrayEncoder(frame_id).encode([shape], stamp),
                                      MarkerArray).markers[0]
        scale = (decoded.scale.x, decoded.scale.y, decoded.scale.z)   # checked above
        centred = shape.kind in ('disc', 'text')
        markers.append(marker(shape.namespace, shape.id, MARKER_TYPES[shape.kind], Marker.ADD,
                              shape.points[0] if centred else (0.0, 0.0), scale, shape.colour,
                              () if centred else shape.points, shape.text))
    return bytes(store.serialize_cdr(types[MARKER_ARRAY](markers=markers), MARKER_ARRAY))


@pytest.mark.parametrize('frame_id', ['platform', 'map', 'a_frame_of_odd_length'])
def test_the_bytes_are_rosbags_serialization_of_the_same_array(frame_id):
    """Every kind of shape, at every alignment a string of another length leaves it at."""
    scene = a_scene_with_everything()
    shapes = scene.robot_shapes() + scene.route_shapes(only_last=False) + scene.static_shapes()
    encoder = MarkerArrayEncoder(frame_id)
    for clear_first in (False, True):
        assert encoder.encode(shapes, (7, 5), clear_first) == \
            rosbags_marker_array(shapes, (7, 5), frame_id, clear_first)

