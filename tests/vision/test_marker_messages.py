"""The markers' wire format (omni_micro_vision.marker_messages): the bytes markers_node
publishes read back, with rclpy's own deserializer, as the MarkerArray of the scene's shapes."""

import math

import pytest
from rclpy.serialization import deserialize_message
from visualization_msgs.msg import Marker, MarkerArray

from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.marker_messages import MarkerArrayEncoder
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
