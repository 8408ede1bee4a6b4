"""What a viewer draws (omni_micro_vision.scene): the robot's geometry, the route's segments,
a new goal clearing the last one's captures, and the Foxglove layout naming what exists."""

import itertools
import json
import math
from pathlib import Path

import pytest

from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.scene import (
    FLEET_COLOURS,
    ROUTE_SEGMENT_POINTS,
    ROUTE_SPACING_M,
    RobotGeometry,
    Scene,
)

ROOT = Path(__file__).resolve().parents[2]


def test_wheels_sit_at_l_from_the_centre_120_deg_apart_wheel_1_at_45_deg():
    geometry = RobotGeometry()
    contacts = geometry.wheel_contacts(0.01, 0.02, math.radians(30))
    for k, (x, y) in enumerate(contacts):
        assert math.hypot(x - 0.01, y - 0.02) == pytest.approx(4.15e-3)
        angle = math.degrees(math.atan2(y - 0.02, x - 0.01))
        assert angle == pytest.approx((30 + 45 + 120 * k + 180) % 360 - 180)


def test_the_robot_is_drawn_where_the_odometry_puts_it_with_wheels_along_the_steering():
    scene = Scene(DEFAULT_RIG)
    assert scene.robot_shapes() == []          # nothing before the first odometry
    scene.on_odometry(0.05, -0.01, 0.3)
    scene.on_steering(0.2)
    shapes = {shape.namespace: shape for shape in scene.robot_shapes()}
    assert shapes['robot/chassis'].points == ((0.05, -0.01),)
    assert shapes['robot/chassis'].size_m == pytest.approx(9e-3)
    wheels = shapes['robot/wheels'].points
    for k in range(3):
        (x0, y0), (x1, y1) = wheels[2 * k], wheels[2 * k + 1]
        assert math.atan2(y1 - y0, x1 - x0) == pytest.approx(0.5)     # phi + steering
    assert shapes['robot/wheel_1'].points[0] == pytest.approx(
        RobotGeometry().wheel_contacts(0.05, -0.01, 0.3)[0])


def test_a_fleet_robot_is_drawn_in_its_colour_with_its_label_above_it():
    scene = Scene(DEFAULT_RIG, robot_colour=FLEET_COLOURS[2], label='robot_2')
    scene.on_odometry(0.05, -0.01, 0.3)
    shapes = {shape.namespace: shape for shape in scene.robot_shapes()}
    assert shapes['robot/chassis'].colour == FLEET_COLOURS[2]
    label = shapes['robot/label']
    assert (label.kind, label.text) == ('text', 'robot_2')
    (x, y), = label.points
    assert x == 0.05 and y > -0.01 + 4.5e-3     # above the 9 mm chassis
    # A single robot: no label, its own colour.
    alone = Scene(DEFAULT_RIG)
    alone.on_odometry(0.05, -0.01, 0.3)
    assert 'robot/label' not in {shape.namespace for shape in alone.robot_shapes()}
    assert len(set(FLEET_COLOURS)) == 10


def test_the_route_is_decimated_into_segments_of_which_only_the_last_changes():
    scene = Scene(DEFAULT_RIG)
    for step in range(200):
        scene.on_odometry(step * ROUTE_SPACING_M * 0.6, 0.0, 0.0)   # every other one kept
    assert len(scene.route) == 100
    segments = [s for s in scene.route_shapes(only_last=False) if s.namespace == 'route']
    assert [len(s.points) for s in segments[:-1]] == [ROUTE_SEGMENT_POINTS] * (
        len(segments) - 1)
    for before, after in itertools.pairwise(segments):
        assert before.points[-1] == after.points[0]      # no gap between segments
    last = scene.route_shapes(only_last=True)
    assert [s.id for s in last] == [segments[-1].id]
    # Far from the micro field, no close-up copy.
    assert not [s for s in scene.route_shapes(only_last=False) if s.namespace == 'micro/route']


def test_a_new_goal_clears_the_last_goals_captures_and_moves():
    scene = Scene(DEFAULT_RIG)
    scene.on_odometry(0.1, 0.0, 0.0)
    scene.on_goal(0.1002, 0.0)
    scene.on_capture('micro', 0.1, 0.0)
    scene.on_capture_uncertainty('micro', 0.1, 0.0, 3.5e-7)
    scene.on_move(0.0, 2e-4)
    namespaces = {s.namespace for s in scene.static_shapes()}
    assert {'micro/capture_uncertainty/micro', 'moves', 'micro/tolerance'} <= namespaces
    disc = next(s for s in scene.static_shapes()
                if s.namespace == 'micro/capture_uncertainty/micro')
    assert disc.size_m == pytest.approx(7e-7)
    move = next(s for s in scene.static_shapes() if s.namespace == 'moves')
    assert math.dist(*move.points) == pytest.approx(2e-4)
    scene.on_goal(0.1, 0.0005)
    assert scene.cleared and not scene.captures and not scene.moves
    assert {'moves', 'captures/micro'}.isdisjoint({s.namespace for s in scene.static_shapes()})


def test_the_foxglove_layout_shows_topics_and_namespaces_that_exist():
    from omni_micro_tools.viewer_node import VIEW_TOPICS

    layout = json.loads((ROOT / 'foxglove' / 'omni-micro.json').read_text())

    def panels(node):
        return [node] if isinstance(node, str) else panels(node['first']) + panels(
            node['second'])

    assert sorted(panels(layout['layout'])) == sorted(layout['configById'])
    scene = Scene(DEFAULT_RIG)
    scene.on_odometry(0.1, 0.0, 0.0)
    scene.on_odometry(0.1001, 0.0, 0.0)
    scene.on_goal(0.1, 0.0)
    scene.on_capture('macro', 0.1, 0.0)
    scene.on_capture('micro', 0.1, 0.0)
    drawn = {s.namespace for s in scene.static_shapes() + scene.route_shapes(only_last=False)
             + scene.robot_shapes()}
    for name, config in layout['configById'].items():
        if name.startswith('3D!'):
            assert set(config['topics']) <= set(VIEW_TOPICS)
            assert set(config['topics']['/markers']['namespaces']) <= drawn
        for path in config.get('paths', []):
            assert path['value'].split('.')[0] in VIEW_TOPICS
        if 'topicPath' in config:
            assert config['topicPath'] in VIEW_TOPICS


def test_a_turned_camera_s_field_is_drawn_turned_about_its_centre():
    yaw = math.radians(2.0)
    scene = Scene(DEFAULT_RIG, camera_yaw_rad={'micro': yaw})
    fields = {shape.id: shape for shape in scene.static_shapes(frozenset({'fields'}))
              if shape.namespace == 'fields'}
    (cx, cy), (w, h) = DEFAULT_RIG.micro.center_m, DEFAULT_RIG.micro.field_m
    first = fields[1].points[0]      # the corner (-w/2, -h/2), turned by 2 deg
    assert first == pytest.approx((cx - w / 2 * math.cos(yaw) + h / 2 * math.sin(yaw),
                                   cy - w / 2 * math.sin(yaw) - h / 2 * math.cos(yaw)))
    assert fields[0].points[0] == pytest.approx((0.05 - 0.075, -0.075))   # macro: square
