"""What a viewer draws of a run, from the graph's messages alone: robot, route, captures, moves,
camera fields, goal and the slip at each wheel. No rclpy: ``markers_node`` turns the shapes into
visualization_msgs/Marker, ``analyze --animate`` into matplotlib artists, so both draw the same.

Everything is in the ``platform`` frame, in metres. The route is 100 mm long and the micro field
2 mm wide: each shape is drawn at the macro view's widths, and the ones that matter near the goal
again in the ``micro/...`` namespaces at the micro view's widths (``MICRO_SCALE`` finer), so that
a 3D panel framed on either shows lines of a legible width.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from omni_micro_common.conventions import GOAL_TOLERANCE_M, STEERING_JOINT, WHEEL_JOINTS
from omni_micro_sim.parameters import RobotParameters
from omni_micro_vision.camera import CameraRig

Colour = tuple[float, float, float, float]
Triple = tuple[float, float, float]
THIRD_TURN = 2.0 * math.pi / 3.0          # wheels 2 and 3 sit 120 and 240 deg from wheel 1
Point = tuple[float, float]

# Line widths of the macro view (a 15 cm field): 0.3 mm reads at a glance.
MACRO_WIDTH_M = 3.0e-4
# The micro field is 75 times smaller than the macro one.
MICRO_SCALE = 1.0 / 75.0
# A new route point once the robot has moved this far (the route stays a few hundred points).
ROUTE_SPACING_M = 2.0e-5
ROUTE_SEGMENT_POINTS = 32        # a line strip per segment: only the last one changes
# Captures as sphere lists of this many: a new capture re-sends the last list only (one list of
# every capture re-sent on each capture was a third of everything the markers sent).
CAPTURE_LIST_POINTS = 32
# The micro close-up's copy of a route segment only where it comes this near the micro field.
MICRO_ROUTE_MARGIN_M = 1.0e-3
# The groups of shapes that change on an event (Scene.static_shapes).
EVENT_GROUPS = frozenset({'fields', 'goal', 'captures', 'moves'})
CAMERA_COLOURS: dict[str, Colour] = {'macro': (0.12, 0.47, 0.71, 1.0),
                                     'micro': (0.84, 0.15, 0.16, 1.0)}
WHITE: Colour = (1.0, 1.0, 1.0, 1.0)
GREY: Colour = (0.55, 0.55, 0.55, 1.0)
ROBOT: Colour = (0.95, 0.65, 0.1, 0.85)
ROUTE: Colour = (0.1, 0.1, 0.1, 1.0)
GOAL: Colour = (0.17, 0.63, 0.17, 1.0)
MOVE: Colour = (0.58, 0.4, 0.74, 1.0)
SLIP_LONGITUDINAL: Colour = (0.84, 0.15, 0.16, 1.0)
SLIP_TRANSVERSE: Colour = (0.12, 0.47, 0.71, 1.0)
# Robot k of a fleet in FLEET_COLOURS[k % 10] (matplotlib's tab10, as fleet --plot
# draws the routes), its chassis a little transparent as the single robot's.
FLEET_COLOURS: tuple[Colour, ...] = tuple(
    (int(code[0:2], 16) / 255, int(code[2:4], 16) / 255, int(code[4:6], 16) / 255, 0.85)
    for code in ('1f77b4', 'ff7f0e', '2ca02c', 'd62728', '9467bd', '8c564b', 'e377c2',
                 '7f7f7f', 'bcbd22', '17becf'))
LABEL: Colour = (0.1, 0.1, 0.1, 1.0)
LABEL_HEIGHT_M = 3.0e-3


@dataclass(frozen=True)
class Shape:
    """One marker: ``kind`` is arrow (points = tail, head), disc (points = centre; size =
    diameter), sphere_list, line_strip, line_list or text (points = anchor)."""

    namespace: str
    id: int
    kind: str
    points: tuple[Point, ...]
    colour: Colour
    size_m: float              # line width, sphere or disc diameter, text height
    text: str = ''


def slip_of(names: Sequence[str], velocities: Sequence[float]) -> tuple[Triple, Triple]:
    """Longitudinal and transverse slip of the three wheels from a /wheel_slip JointState."""
    speeds = dict(zip(names, velocities, strict=False))
    longitudinal = [float(speeds.get(f'wheel_{k}_longitudinal', 0.0)) for k in (1, 2, 3)]
    transverse = [float(speeds.get(f'wheel_{k}_transverse', 0.0)) for k in (1, 2, 3)]
    return ((longitudinal[0], longitudinal[1], longitudinal[2]),
            (transverse[0], transverse[1], transverse[2]))


def move_of(joint_names: Sequence[str], first: Sequence[float], last: Sequence[float],
            wheel_radius_m: float) -> tuple[float, float]:
    """Steering angle and planned length of a /wheel_trajectory move, from its first and last
    points' positions (the wheel command contract: joint order by name)."""
    steering = float(first[list(joint_names).index(STEERING_JOINT)])
    wheel = list(joint_names).index(WHEEL_JOINTS[1])
    return steering, abs(float(last[wheel]) - float(first[wheel])) * wheel_radius_m


_NOMINAL = RobotParameters()


@dataclass(frozen=True)
class RobotGeometry:
    """What a viewer draws of the robot; by default the nominal robot's own dimensions."""

    chassis_radius_m: float = _NOMINAL.chassis_radius_m
    wheel_distance_m: float = _NOMINAL.wheel_distance_m
    wheel_radius_m: float = _NOMINAL.wheel_radius_m
    wheel1_angle_rad: float = _NOMINAL.wheel1_angle_rad
    wheel_offsets_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def wheel_contacts(self, x: float, y: float, phi: float) -> list[Point]:
        angles = [phi + self.wheel1_angle_rad + k * THIRD_TURN for k in range(3)]
        return [(x + self.wheel_distance_m * math.cos(angle),
                 y + self.wheel_distance_m * math.sin(angle)) for angle in angles]

    def rolling_headings(self, phi: float, steering: float) -> list[float]:
        return [phi + steering + offset for offset in self.wheel_offsets_rad]


@dataclass
class Capture:
    camera: str
    x_m: float
    y_m: float
    radius_95_m: float | None = None


@dataclass
class Scene:
    """The state a viewer draws, fed message by message (``on_*``)."""

    rig: CameraRig
    robot: RobotGeometry = field(default_factory=RobotGeometry)
    tolerance_m: float = GOAL_TOLERANCE_M
    slip_arrow_s: float = 2.0            # arrow length (m) per slip speed (m/s)
    # Who the robot is, on a platform shared with others: its chassis's colour, and a label
    # beside it ('' for none: a single robot).
    robot_colour: Colour = ROBOT
    label: str = ''
    # How each camera is turned about its centre (``yaw_rad`` of camera_node, tracker_node).
    camera_yaw_rad: dict[str, float] = field(default_factory=dict)
    pose: tuple[float, float, float] | None = None
    steering_rad: float = 0.0
    goal_m: Point | None = None
    start_m: Point | None = None
    route: list[Point] = field(default_factory=list)
    captures: list[Capture] = field(default_factory=list)
    moves: list[tuple[Point, Point]] = field(default_factory=list)
    slip_longitudinal: tuple[float, float, float] = (0.0, 0.0, 0.0)
    slip_transverse: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cleared: bool = False

    # -- inputs ------------------------------------------------------------------------------
    def on_odometry(self, x: float, y: float, phi: float) -> None:
        self.pose = (x, y, phi)
        if not self.route or math.dist(self.route[-1], (x, y)) >= ROUTE_SPACING_M:
            self.route.append((x, y))

    def on_steering(self, steering_rad: float) -> None:
        self.steering_rad = steering_rad

    def on_goal(self, x: float, y: float) -> None:
        """A new goal: the captures and moves drawn from now on are its own (a soak sends
        fifty); the route goes on. ``cleared`` tells a viewer to drop what it drew."""
        self.goal_m = (x, y)
        self.start_m = (self.pose[0], self.pose[1]) if self.pose else (0.0, 0.0)
        self.cleared = bool(self.captures or self.moves)
        self.captures.clear()
        self.moves.clear()

    def on_capture(self, camera: str, x: float, y: float) -> None:
        self.captures.append(Capture(camera, x, y))

    def on_capture_uncertainty(self, camera: str, x: float, y: float,
                               radius_95_m: float) -> None:
        """The covariance beside a capture: attach it to that capture (same camera, pose)."""
        for capture in reversed(self.captures):
            if capture.camera == camera and math.isclose(capture.x_m, x, abs_tol=1e-12) \
                    and math.isclose(capture.y_m, y, abs_tol=1e-12):
                capture.radius_95_m = radius_95_m
                return

    def on_move(self, steering_rad: float, length_m: float) -> None:
        """A commanded move from the current pose: its direction and planned length."""
        if self.pose is None:
            return
        x, y, phi = self.pose
        heading = phi + steering_rad
        self.moves.append(((x, y), (x + length_m * math.cos(heading),
                                    y + length_m * math.sin(heading))))

    def on_slip(self, longitudinal: tuple[float, float, float],
                transverse: tuple[float, float, float]) -> None:
        self.slip_longitudinal = longitudinal
        self.slip_transverse = transverse

    # -- shapes ------------------------------------------------------------------------------
    def robot_shapes(self) -> list[Shape]:
        """The robot and its slip: what changes every tick."""
        if self.pose is None:
            return []
        x, y, phi = self.pose
        contacts = self.robot.wheel_contacts(x, y, phi)
        headings = self.robot.rolling_headings(phi, self.steering_rad)
        r = self.robot.wheel_radius_m
        wheels: list[Point] = []
        for (cx, cy), heading in zip(contacts, headings, strict=True):
            wheels += [(cx - r * math.cos(heading), cy - r * math.sin(heading)),
                       (cx + r * math.cos(heading), cy + r * math.sin(heading))]
        nose = (x + self.robot.chassis_radius_m * math.cos(phi),
                y + self.robot.chassis_radius_m * math.sin(phi))
        shapes = [
            Shape('robot/chassis', 0, 'disc', ((x, y),), self.robot_colour,
                  2.0 * self.robot.chassis_radius_m),
            Shape('robot/wheels', 0, 'line_list', tuple(wheels), (0.2, 0.2, 0.2, 1.0),
                  4.0 * MACRO_WIDTH_M),
            Shape('robot/wheel_1', 0, 'sphere_list', (contacts[0],), (0.84, 0.15, 0.16, 1.0),
                  1.2e-3),
            Shape('robot/heading', 0, 'arrow', ((x, y), nose), (0.1, 0.1, 0.1, 1.0),
                  2.0 * MACRO_WIDTH_M),
        ]
        for k, ((cx, cy), heading) in enumerate(zip(contacts, headings, strict=True)):
            for name, speed, angle, colour in (
                    ('slip/longitudinal', self.slip_longitudinal[k], heading, SLIP_LONGITUDINAL),
                    ('slip/transverse', self.slip_transverse[k], heading + math.pi / 2,
                     SLIP_TRANSVERSE)):
                length = self.slip_arrow_s * speed
                shapes.append(Shape(name, k, 'arrow', ((cx, cy), (
                    cx + length * math.cos(angle), cy + length * math.sin(angle))), colour,
                    MACRO_WIDTH_M))
        if self.label:
            above = (x, y + self.robot.chassis_radius_m + LABEL_HEIGHT_M)
            shapes.append(Shape('robot/label', 0, 'text', (above,), LABEL, LABEL_HEIGHT_M,
                                text=self.label))
        return shapes

    def route_shapes(self, only_last: bool) -> list[Shape]:
        """The route as line strips of ``ROUTE_SEGMENT_POINTS``; consecutive ones share a point.
        ``only_last``: just the segment still growing."""
        count = max(1, math.ceil((len(self.route) - 1) / (ROUTE_SEGMENT_POINTS - 1)))
        first = count - 1 if only_last else 0
        # A robot among others draws its route in its own colour, opaque.
        colour = ROUTE if not self.label else (*self.robot_colour[:3], 1.0)
        shapes = []
        for segment in range(first, count):
            start = segment * (ROUTE_SEGMENT_POINTS - 1)
            points = tuple(self.route[start:start + ROUTE_SEGMENT_POINTS])
            if len(points) < 2:
                continue
            shapes.append(Shape('route', segment, 'line_strip', points, colour, MACRO_WIDTH_M))
            if self._near_micro_field(points):
                shapes.append(Shape('micro/route', segment, 'line_strip', points, colour,
                                    MACRO_WIDTH_M * MICRO_SCALE))
        return shapes

    def _near_micro_field(self, points: tuple[Point, ...]) -> bool:
        (cx, cy), (w, h) = self.rig.micro.center_m, self.rig.micro.field_m
        return any(abs(x - cx) <= w / 2 + MICRO_ROUTE_MARGIN_M
                   and abs(y - cy) <= h / 2 + MICRO_ROUTE_MARGIN_M for x, y in points)

    def static_shapes(self, groups: frozenset[str] = EVENT_GROUPS,
                      newest_only: bool = False) -> list[Shape]:
        """What changes only on an event, by group: ``fields``, ``goal`` (with the ideal route
        and the tolerance), ``captures`` and ``moves``. ``newest_only``: of the per-capture
        discs and the move arrows, only the latest (a viewer keeps the others)."""
        shapes = []
        if 'fields' in groups:
            shapes += self._field_shapes()
        if 'goal' in groups and self.goal_m is not None:
            gx, gy = self.goal_m
            circle = tuple((gx + self.tolerance_m * math.cos(a / 32 * 2 * math.pi),
                            gy + self.tolerance_m * math.sin(a / 32 * 2 * math.pi))
                           for a in range(33))
            shapes += [
                Shape('goal', 0, 'sphere_list', (self.goal_m,), GOAL, 1.5e-3),
                Shape('micro/goal', 0, 'sphere_list', (self.goal_m,), GOAL,
                      1.5e-3 * MICRO_SCALE),
                Shape('micro/tolerance', 0, 'line_strip', circle, GOAL,
                      max(self.tolerance_m / 15, 2e-8)),
            ]
            if self.start_m is not None:
                shapes.append(Shape('ideal_route', 0, 'line_strip', (self.start_m, self.goal_m),
                                    GREY, MACRO_WIDTH_M / 2))
        if 'captures' in groups:
            shapes += self._capture_shapes(newest_only)
        if 'moves' in groups:
            first = max(0, len(self.moves) - 1) if newest_only else 0
            for index in range(first, len(self.moves)):
                tail, head = self.moves[index]
                length = math.dist(tail, head)
                shapes.append(Shape('moves', index, 'arrow', (tail, head), MOVE,
                                    min(MACRO_WIDTH_M, max(length / 10, 1e-7))))
        return shapes

    def _field_shapes(self) -> list[Shape]:
        shapes = []
        for index, camera in enumerate((self.rig.macro, self.rig.micro)):
            (cx, cy), (w, h) = camera.center_m, camera.field_m
            yaw = self.camera_yaw_rad.get(camera.name, 0.0)
            cos, sin = math.cos(yaw), math.sin(yaw)
            corners = tuple((cx + cos * sx * w / 2 - sin * sy * h / 2,
                             cy + sin * sx * w / 2 + cos * sy * h / 2)
                            for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1), (-1, -1)))
            width = MACRO_WIDTH_M if camera is self.rig.macro else MACRO_WIDTH_M * MICRO_SCALE
            shapes.append(Shape('fields', index, 'line_strip', corners,
                                CAMERA_COLOURS.get(camera.name, GREY), width))
            shapes.append(Shape('fields/labels', index, 'text', (corners[3],),
                                CAMERA_COLOURS.get(camera.name, GREY),
                                12 * width, f'{camera.name} camera'))
        return shapes

    def _capture_shapes(self, newest_only: bool) -> list[Shape]:
        shapes = []
        for name, colour in CAMERA_COLOURS.items():
            seen = [c for c in self.captures if c.camera == name]
            if not seen:
                continue
            lists = math.ceil(len(seen) / CAPTURE_LIST_POINTS)
            for part in range(lists - 1 if newest_only else 0, lists):
                points = tuple((c.x_m, c.y_m) for c in seen[part * CAPTURE_LIST_POINTS:
                                                             (part + 1) * CAPTURE_LIST_POINTS])
                shapes.append(Shape(f'captures/{name}', part, 'sphere_list', points, colour,
                                    8e-4))
                shapes.append(Shape(f'micro/captures/{name}', part, 'sphere_list', points,
                                    colour, 8e-4 * MICRO_SCALE))
            first = len(seen) - 1 if newest_only else 0
            for index in range(first, len(seen)):
                capture = seen[index]
                if capture.radius_95_m is not None:
                    faded = (colour[0], colour[1], colour[2], 0.3)
                    shapes.append(Shape(f'micro/capture_uncertainty/{name}', index, 'disc',
                                        ((capture.x_m, capture.y_m),), faded,
                                        2.0 * capture.radius_95_m))
        return shapes
