"""The picture of a fleet's run, as ``fleet --plot`` and ``analyze`` of a fleet's bag
draw it: the whole platform, every robot's route in its colour (the colour its markers and
chassis have), its start (a dashed disc) and end (a filled disc) labelled with its number, its
goals (crosses), the micro field, and beside it the micro field close up.

Robots on the roadmap often drive the same segment one after the other; drawn solid, the last
one drawn hides the others. So with several robots each route is dashed, the dashes of robots
next in number offset from each other: where routes overlap, their colours alternate along it.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

from omni_micro_common.conventions import PLATFORM_CENTER_M, PLATFORM_SIZE_M
from omni_micro_sim.parameters import RobotParameters
from omni_micro_vision.camera import DEFAULT_RIG, CameraRig
from omni_micro_vision.scene import FLEET_COLOURS

# Dashes of overlapping routes: this long (points), and this many robots before the pattern
# repeats (robots k and k + DASH_GROUP share their dashes' places).
DASH_PT = 4.0
DASH_GROUP = 3
# Around the micro field, the close-up shows this much of the platform.
CLOSE_UP_HALF_M = 1.5e-3


@dataclass(frozen=True)
class DrawnRobot:
    """What the picture shows of robot ``index``: its route (n x 2, m), its goals (g x 2, m) in
    order, how many it reached, and where it started (the route's first point if None)."""

    index: int
    name: str
    route_m: np.ndarray
    goals_m: np.ndarray
    goals_reached: int
    start_m: tuple[float, float] | None = None


def colour_of(index: int) -> tuple[float, float, float]:
    """Robot ``index``'s colour, as its markers and chassis have it."""
    red, green, blue, _ = FLEET_COLOURS[index % len(FLEET_COLOURS)]
    return red, green, blue


def route_style(index: int, count: int) -> str | tuple[float, tuple[float, float]]:
    """Solid for one robot; for several, dashes offset robot by robot (module docstring)."""
    if count == 1:
        return '-'
    group = min(count, DASH_GROUP)
    return ((index % group) * DASH_PT, (DASH_PT, DASH_PT * (group - 1)))


def fleet_routes_png(robots: list[DrawnRobot], title: str, rig: CameraRig = DEFAULT_RIG,
                     goal_word: str = 'goal') -> bytes:
    """The picture (a PNG's bytes) of ``robots``' runs; ``goal_word``: what its crosses are (a
    plan's goals, or a bag's goal poses: every point of the robots' legs)."""
    import matplotlib

    matplotlib.use('Agg')
    from matplotlib import pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle, Rectangle

    figure = plt.figure(figsize=(10.0, 7.0))
    platform = figure.add_axes((0.06, 0.08, 0.6, 0.84))
    close_up = figure.add_axes((0.71, 0.45, 0.27, 0.4))
    radius_mm = RobotParameters.chassis_radius_m * 1e3   # the discs: the chassis
    micro = rig.micro
    for axes in (platform, close_up):
        axes.add_patch(Rectangle(((micro.center_m[0] - micro.field_m[0] / 2) * 1e3,
                                  (micro.center_m[1] - micro.field_m[1] / 2) * 1e3),
                                 micro.field_m[0] * 1e3, micro.field_m[1] * 1e3, color='k',
                                 fill=False, lw=1.2))
    for robot in robots:
        colour = colour_of(robot.index)
        route_mm = np.asarray(robot.route_m, dtype=float).reshape(-1, 2) * 1e3
        goals_mm = np.asarray(robot.goals_m, dtype=float).reshape(-1, 2) * 1e3
        style = route_style(robot.index, len(robots))
        for axes in (platform, close_up):
            if len(route_mm):
                axes.plot(route_mm[:, 0], route_mm[:, 1], color=colour, lw=1.6, ls=style)
            if len(goals_mm):
                axes.plot(goals_mm[:, 0], goals_mm[:, 1], 'x', color=colour, ms=7, mew=1.8)
        start = (np.array(robot.start_m) * 1e3 if robot.start_m is not None
                 else route_mm[0] if len(route_mm) else None)
        end = route_mm[-1] if len(route_mm) else None
        for place, filled in ((start, False), (end, True)):
            if place is None:
                continue
            platform.add_patch(Circle(tuple(place), radius_mm, color=colour, fill=filled,
                                      alpha=0.35 if filled else 1.0, ls='-' if filled else '--'))
            platform.annotate(str(robot.index), tuple(place), ha='center', va='center',
                              fontsize=8, color='k' if filled else colour,
                              fontweight='bold' if filled else 'normal')
    (cx, cy), (w, h) = PLATFORM_CENTER_M, PLATFORM_SIZE_M
    platform.set_xlim((cx - w / 2) * 1e3 - 5, (cx + w / 2) * 1e3 + 5)
    platform.set_ylim((cy - h / 2) * 1e3 - 5, (cy + h / 2) * 1e3 + 5)
    platform.set_aspect('equal')
    platform.grid(True, alpha=0.3)
    platform.set(xlabel='x (mm)', ylabel='y (mm)', title=title)
    mx, my = micro.center_m
    close_up.set_xlim((mx - CLOSE_UP_HALF_M) * 1e3, (mx + CLOSE_UP_HALF_M) * 1e3)
    close_up.set_ylim((my - CLOSE_UP_HALF_M) * 1e3, (my + CLOSE_UP_HALF_M) * 1e3)
    close_up.set_aspect('equal')
    close_up.grid(True, alpha=0.3)
    close_up.set_title(f'micro field ({micro.field_m[0] * 1e3:g} mm), close up', fontsize=9)
    close_up.tick_params(labelsize=7)
    legend = [Line2D([], [], color=colour_of(robot.index), lw=1.6,
                     label=f'{robot.name}: {robot.goals_reached}/{len(robot.goals_m)} '
                           f'{goal_word}s')
              for robot in robots]
    legend += [Line2D([], [], ls='', marker='o', mfc='none', mec='k', ms=9,
                      label='start (dashed), its number'),
               Line2D([], [], ls='', marker='o', mfc='0.7', mec='0.7', ms=9,
                      label='end (filled), its number'),
               Line2D([], [], ls='', marker='x', color='k', label=goal_word),
               Line2D([], [], ls='', marker='s', mfc='none', mec='k', label='micro field')]
    figure.legend(handles=legend, loc='lower right', bbox_to_anchor=(0.99, 0.02), fontsize=8,
                  ncol=2 if len(robots) > 12 else 1)
    buffer = io.BytesIO()
    figure.savefig(buffer, format='png', dpi=110)
    plt.close(figure)
    return buffer.getvalue()
