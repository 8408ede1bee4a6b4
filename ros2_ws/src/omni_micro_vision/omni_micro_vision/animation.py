"""`analyze BAG --animate`: the run as a GIF (or MP4), from the bag alone.

The bag's messages are fed, in the order they were recorded, to the same
:class:`omni_micro_vision.scene.Scene` that ``markers_node`` draws from; each frame draws the
scene at one simulated time: the platform with the route forming, captures landing, moves and
the robot, and an inset of the micro field. A fleet's bag (each robot's topics under
``/robot_k/``) gets a scene per robot, each robot in its colour and labelled, as
``/robot_k/markers`` draws it.
"""

from __future__ import annotations

import math
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np

from omni_micro_common.clocks import is_wall_clock
from omni_micro_common.conventions import (
    PLATFORM_CENTER_M,
    PLATFORM_SIZE_M,
    STEERING_JOINT,
    CaptureUncertainty,
    quaternion_to_yaw,
)
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_TOPICS,
    GOAL_TOPIC,
    JOINT_STATES_TOPIC,
    ODOM_TOPIC,
    WHEEL_SLIP_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
    robot_name,
)
from omni_micro_tools.bag_reading import read_bag
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.errors import AnimationError
from omni_micro_vision.fleet_figure import route_style
from omni_micro_vision.scene import FLEET_COLOURS, Scene, Shape, move_of, slip_of

FIGURE_SIZE_IN = (10.0, 4.5)
DPI = 100                      # frames of 1000 x 450 pixels
# Around the platform, so that a robot on its edge is drawn whole.
PLATFORM_MARGIN_MM = 6.0
# The robot as a capture shows it, where the bag has no /odom (a real robot's run).
SEEN = 'seen by a camera'
TOPICS = (ODOM_TOPIC, JOINT_STATES_TOPIC, WHEEL_SLIP_TOPIC, WHEEL_TRAJECTORY_TOPIC, GOAL_TOPIC,
          *CAPTURE_TOPICS.values(), *CAPTURE_COVARIANCE_TOPICS.values())


# One message that changes a scene: the simulated time it was recorded at, whose scene (a robot's
# namespace, '' for a single robot), its topic as a single robot names it, the message.
Event = tuple[int, str, str, Any]


def _events(bag: Path, robots: list[str]) -> list[Event]:
    """Every message that changes a robot's scene (``robots``: the namespaces of a
    fleet's bag; ``['']`` for a single robot's)."""
    data = read_bag(bag, [f'/{robot}{topic}' if robot else topic
                          for robot in robots for topic in TOPICS])
    events: list[Event] = []
    for robot in robots:
        def of(topic: str, robot: str = robot) -> list[tuple[int, Any]]:
            named = f'/{robot}{topic}' if robot else topic
            return list(zip(data.timestamps.get(named, []), data.messages.get(named, []),
                            strict=True))
        events += [(stamp, robot, topic, message) for topic in TOPICS
                   for stamp, message in of(topic)]
        if not of(ODOM_TOPIC):
            # A run with a real robot: the robot drawn where the cameras saw it.
            events += [(stamp, robot, SEEN, message) for topic in CAPTURE_TOPICS.values()
                       for stamp, message in of(topic)]
    if not any(topic in (ODOM_TOPIC, SEEN) for _, _, topic, _ in events):
        raise AnimationError(f'{str(bag)!r} has no /odom and no captures: nothing to animate')
    # The recorder's stamps are simulated time; ties keep the topics' order above.
    events.sort(key=lambda event: event[0])
    return events


def _apply(scene: Scene, topic: str, message: Any) -> None:
    if topic in (ODOM_TOPIC, SEEN):
        pose = message.pose.pose if topic == ODOM_TOPIC else message.pose
        scene.on_odometry(pose.position.x, pose.position.y,
                          quaternion_to_yaw(pose.orientation.z, pose.orientation.w))
    elif topic == JOINT_STATES_TOPIC and STEERING_JOINT in message.name:
        scene.on_steering(message.position[message.name.index(STEERING_JOINT)])
    elif topic == WHEEL_SLIP_TOPIC:
        scene.on_slip(*slip_of(message.name, message.velocity))
    elif topic == WHEEL_TRAJECTORY_TOPIC and len(message.points) >= 2:
        scene.on_move(*move_of(message.joint_names, message.points[0].positions,
                               message.points[-1].positions, scene.robot.wheel_radius_m))
    elif topic == GOAL_TOPIC:
        scene.on_goal(message.pose.position.x, message.pose.position.y)
    elif topic.endswith('/pose'):
        scene.on_capture(topic.split('/')[2], message.pose.position.x, message.pose.position.y)
    elif topic.endswith('/pose_with_covariance'):
        pose = message.pose.pose
        uncertainty = CaptureUncertainty.from_covariance(list(message.pose.covariance))
        scene.on_capture_uncertainty(topic.split('/')[2], pose.position.x, pose.position.y,
                                     uncertainty.radius_95_m)


def _draw(axis: Any, shapes: list[Shape], micro: bool, route_style: Any = '-') -> None:
    """Shapes in mm; line widths in points, so that both views stay legible. ``route_style``:
    the route's line style (a robot among others: :func:`.fleet_figure.route_style`)."""
    from matplotlib.patches import Circle

    for shape in shapes:
        # The inset shows the micro close-up's own shapes and the fields; the 9 mm robot and
        # its moves would cover it.
        if micro != shape.namespace.startswith('micro/') and shape.namespace != 'fields':
            continue
        points = np.array(shape.points) * 1e3
        colour = shape.colour
        if shape.kind in ('line_strip', 'line_list'):
            if shape.kind == 'line_list':
                for start in range(0, len(points) - 1, 2):
                    axis.plot(points[start:start + 2, 0], points[start:start + 2, 1],
                              color=colour, linewidth=2.5)
            else:
                axis.plot(points[:, 0], points[:, 1], color=colour, linewidth=1.2,
                          linestyle=route_style if shape.namespace.endswith('route') else '-')
        elif shape.kind == 'sphere_list':
            axis.scatter(points[:, 0], points[:, 1], s=14, color=colour, zorder=3)
        elif shape.kind == 'disc':
            axis.add_patch(Circle(tuple(points[0]), shape.size_m * 1e3 / 2, color=colour,
                                  alpha=min(colour[3], 0.5), zorder=2))
        elif shape.kind == 'text' and shape.namespace == 'robot/label':
            axis.annotate(shape.text, tuple(points[0]), ha='center', va='bottom', fontsize=8,
                          color=colour)
        elif shape.kind == 'arrow' and math.dist(*shape.points) > 0:
            axis.annotate('', xy=tuple(points[1]), xytext=tuple(points[0]),
                          arrowprops={'arrowstyle': '->', 'color': colour, 'lw': 1.2})


def animate(bag: Path, target: Path, frames: int, fps: int, still: Path,
            robots: list[int] | None = None) -> int:
    """Render ``frames`` frames to ``target`` (.gif, or .mp4 where ffmpeg exists), and the
    last one to ``still`` (a PNG). ``robots``: the robots of a fleet's bag, all drawn."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib import animation
    from tqdm import tqdm

    if target.suffix == '.mp4' and shutil.which('ffmpeg') is None:
        raise AnimationError('an MP4 needs ffmpeg, which is not installed here; give a .gif')
    names = [robot_name(k) for k in robots] if robots else ['']
    events = _events(bag, names)
    first, last = events[0][0], events[-1][0]
    clock = 'on the wall clock' if is_wall_clock(first * 1e-9) else 'simulated'
    times = np.linspace(first, last, frames)
    scenes = {name: Scene(DEFAULT_RIG) for name in names} if not robots else {
        name: Scene(DEFAULT_RIG, robot_colour=FLEET_COLOURS[k % len(FLEET_COLOURS)], label=name)
        for k, name in zip(robots, names, strict=True)}
    fig = plt.figure(figsize=FIGURE_SIZE_IN, dpi=DPI)
    main = fig.add_axes((0.07, 0.12, 0.6, 0.76))
    inset = fig.add_axes((0.72, 0.12, 0.26, 0.76))
    title = fig.suptitle('')
    cursor = 0
    bar = tqdm(total=frames, unit='frame', desc='animate', file=sys.stderr, mininterval=0.5)

    def frame(index: int) -> None:
        nonlocal cursor
        while cursor < len(events) and events[cursor][0] <= times[index]:
            _, robot, topic, message = events[cursor]
            _apply(scenes[robot], topic, message)
            cursor += 1
        for axis, micro in ((main, False), (inset, True)):
            axis.cla()
            for k, scene in zip(robots or [0], scenes.values(), strict=True):
                _draw(axis, scene.static_shapes() + scene.route_shapes(only_last=False)
                      + scene.robot_shapes(), micro, route_style(k, len(scenes)))
            axis.set_aspect('equal')
            axis.grid(True, alpha=0.3)
        # The whole platform, the micro field well inside it: where every robot may go.
        (cx, cy), (w, h) = PLATFORM_CENTER_M, PLATFORM_SIZE_M
        main.set_xlim((cx - w / 2) * 1e3 - PLATFORM_MARGIN_MM, (cx + w / 2) * 1e3
                      + PLATFORM_MARGIN_MM)
        main.set_ylim((cy - h / 2) * 1e3 - PLATFORM_MARGIN_MM, (cy + h / 2) * 1e3
                      + PLATFORM_MARGIN_MM)
        main.set(xlabel='x (mm)', ylabel='y (mm)', title='platform (15 cm field)')
        title.set_text(f'{bag.name}: t = {(times[index] - first) * 1e-9:6.2f} s {clock}')
        (cx, cy), (w, h) = DEFAULT_RIG.micro.center_m, DEFAULT_RIG.micro.field_m
        inset.set_xlim((cx - w / 2) * 1e3, (cx + w / 2) * 1e3)
        inset.set_ylim((cy - h / 2) * 1e3, (cy + h / 2) * 1e3)
        for scene in scenes.values():
            if scene.pose is not None:
                inset.plot(scene.pose[0] * 1e3, scene.pose[1] * 1e3, 'x',
                           color=scene.robot_colour[:3] if robots else 'k')
        inset.set_title('micro field (2 mm)', fontsize=9)
        inset.tick_params(labelsize=7)
        inset.locator_params(nbins=5)

    movie = animation.FuncAnimation(fig, frame, frames=frames, repeat=False)
    writer = (animation.PillowWriter(fps=fps) if target.suffix == '.gif'
              else animation.FFMpegWriter(fps=fps))
    try:
        # Progress from the writer (the animation also draws a frame to initialise itself).
        movie.save(str(target), writer=writer, dpi=DPI,
                   progress_callback=lambda done, _: bar.update(done + 1 - bar.n))
        fig.savefig(still, dpi=DPI)
    finally:
        bar.close()
        plt.close(fig)
    return frames
