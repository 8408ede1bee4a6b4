"""What a fleet run is given: the robots (where they start, their wheels' offsets, their
controllers) and their tasks, from YAML files or drawn from a seed; every bad value named in one
line.

Robots file::

    robots:
      - start_mm: [0, 0]
        wheel_offsets_deg: [0, 3, 2]      # optional: drawn from the seed (within +-3 deg)
        controller: servo                 # optional: paper, model, servo or open-loop
                                          # (default: --controller)
      - start_mm: [100, 0]

Tasks file (robots by index; goals in order; ``after``: not before that robot's goal)::

    tasks:
      robot_0:
        - goal_mm: [100.2, 0.1]           # in the micro field: reached to 3 um
        - goal_mm: [40, 40]
      robot_1:
        - goal_mm: [100, -0.3]
          after: [0, 1]                   # robot 0's goal 1 reached first
          tolerance_um: 10                # optional
"""

from __future__ import annotations

import math
import random
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

from omni_micro_common.conventions import MICRO_FIELD_CENTER_M
from omni_micro_common.topic_names import robot_name
from omni_micro_control.errors import FleetFileError
from omni_micro_control.feedback_config import MODES
from omni_micro_control.fleet_plan import Task
from omni_micro_sim.parameters import RobotParameters

# What drives a robot of a fleet: a controller mode, or open loop (each goal of its legs one
# move toward it, for the time the nominal robot takes, with no feedback after: where it drifts
# to is where the next leg starts from).
OPEN_LOOP = 'open-loop'
ROBOT_CONTROLLERS = (*MODES, OPEN_LOOP)


def controller_settings(controller: str) -> dict[str, object]:
    """The controller's parameters (FeedbackConfig's) that make it drive as ``controller``
    (ROBOT_CONTROLLERS) says: open loop is the paper's rule's first move, and no other."""
    if controller == OPEN_LOOP:
        return {'mode': 'paper', 'open_loop_to_goal': True}
    return {'mode': controller}


# Wheel offsets drawn per robot when a file does not give them: as large as the paper's Fig. 8
# robot's (0, 3, 2 deg).
DRAWN_OFFSET_DEG = 3.0
# Start places of --robots N and the macro goals drawn: a 20 mm lattice on the platform, two
# clearances apart, away from the micro field (its approach stays free).
LATTICE_M = [(0.02 * i, 0.02 * j) for i in range(-1, 5) for j in range(-3, 4)]
MAX_ROBOTS = len(LATTICE_M)
# The lattice's places beyond it, on the micro field's side: goals too when the lattice's own
# (39 away from the micro field) are fewer than the robots.
LATTICE_BEYOND_M = [(0.02 * i, 0.02 * j) for i in range(5, 7) for j in range(-3, 4)]
# Goals drawn in the micro field lie this close to its centre (it is 2 mm square).
MICRO_GOAL_SPREAD_M = 0.5e-3


@dataclass(frozen=True)
class Fleet:
    starts_m: list[tuple[float, float]]
    robots: list[RobotParameters]
    offsets_deg: list[tuple[float, float, float]]
    tasks: list[list[Task]]
    controllers: list[str]                  # each robot's controller mode (MODES)


def _load(path: Path, key: str) -> Any:
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as error:
        raise FleetFileError(f'cannot read {str(path)!r}: {error.strerror or error}') from None
    except yaml.YAMLError as error:
        raise FleetFileError(f'{str(path)!r} is not YAML: {str(error).splitlines()[0]}') from None
    if not isinstance(data, dict) or key not in data:
        raise FleetFileError(f'{str(path)!r} must be a mapping with {key!r} at its top, got '
                         f'{type(data).__name__}')
    return data[key]


def _pair(where: str, value: object, scale: float) -> tuple[float, float]:
    if (not isinstance(value, list | tuple) or len(value) != 2
            or not all(isinstance(v, int | float) and not isinstance(v, bool)
                       and math.isfinite(v) for v in value)):
        raise FleetFileError(f'{where} must be two finite numbers [x, y], got {value!r}')
    return float(value[0]) * scale, float(value[1]) * scale


def _offsets(where: str, value: object) -> tuple[float, float, float]:
    if (not isinstance(value, list | tuple) or len(value) != 3
            or not all(isinstance(v, int | float) and not isinstance(v, bool)
                       and math.isfinite(v) and abs(v) <= 45.0 for v in value)):
        raise FleetFileError(f'{where} must be three numbers of degrees within +-45, got '
                             f'{value!r}')
    return float(value[0]), float(value[1]), float(value[2])


def robot_parameters(offsets_deg: tuple[float, float, float]) -> RobotParameters:
    first, second, third = (math.radians(value) for value in offsets_deg)
    return RobotParameters(wheel_offsets_rad=(first, second, third))


def drawn_offsets(rng: random.Random) -> tuple[float, float, float]:
    return tuple(round(rng.uniform(-DRAWN_OFFSET_DEG, DRAWN_OFFSET_DEG), 2)
                 for _ in range(3))  # type: ignore[return-value]


def robots_from(spec: str, seed: int, controller: str = 'paper') -> tuple[
        list[tuple[float, float]], list[tuple[float, float, float]], list[str]]:
    """Starts, wheel offsets and controller modes of ``--robots``: a count (lattice places, each
    robot's controller ``controller``) or a YAML file (a robot's own, else ``controller``)."""
    rng = random.Random(f'robots {seed}')
    # A number, whole or not, signed or not, is a count (-1 is no file of robots).
    if re.fullmatch(r'[+-]?(\d+\.?\d*|\.\d+)', spec.strip()):
        number = float(spec)
        if number != int(number) or not 1 <= number <= MAX_ROBOTS:
            raise FleetFileError(f'--robots must be a whole number 1..{MAX_ROBOTS} or a YAML '
                                 f'file, got {spec!r}')
        count = int(number)
        places = _spread_starts(count)
        return places, [drawn_offsets(rng) for _ in places], [controller] * count
    path = Path(spec)
    entries = _load(path, 'robots')
    if not isinstance(entries, list) or not entries:
        raise FleetFileError(f'{spec!r}: robots must be a list of robots, got {entries!r}')
    starts, offsets, controllers = [], [], []
    for index, entry in enumerate(entries):
        where = f'{spec!r}: robots[{index}]'
        entry = _mapping(where, entry, ('start_mm', 'wheel_offsets_deg', 'controller'))
        starts.append(_pair(f'{where}.start_mm', entry['start_mm'], 1e-3))
        offsets.append(_offsets(f'{where}.wheel_offsets_deg', entry['wheel_offsets_deg'])
                       if 'wheel_offsets_deg' in entry else drawn_offsets(rng))
        own = entry.get('controller', controller)
        if own not in ROBOT_CONTROLLERS:
            raise FleetFileError(f'{where}.controller must be one of '
                                 f'{", ".join(ROBOT_CONTROLLERS)}, got {own!r}')
        controllers.append(own)
    return starts, offsets, controllers


def _spread_starts(count: int) -> list[tuple[float, float]]:
    """Lattice places from the platform's left edge, column by column."""
    return sorted(LATTICE_M)[:count]


def tasks_from(path: Path, robots: int) -> list[list[Task]]:
    entries = _load(path, 'tasks')
    where = f'{str(path)!r}: tasks'
    if not isinstance(entries, dict):
        raise FleetFileError(f'{where} must map robot_0, robot_1, ... to goals, got {entries!r}')
    names = {robot_name(k): k for k in range(robots)}
    unknown = sorted(set(map(str, entries)) - set(names))
    if unknown:
        raise FleetFileError(f'{where} names {unknown}: the robots are '
                             f'{robot_name(0)}..{robot_name(robots - 1)}')
    tasks: list[list[Task]] = [[] for _ in range(robots)]
    for name, goals in entries.items():
        if not isinstance(goals, list):
            raise FleetFileError(f'{where}.{name} must be a list of goals, got {goals!r}')
        for index, goal in enumerate(goals):
            tasks[names[str(name)]].append(_task(f'{where}.{name}[{index}]', goal))
    return tasks


def _mapping(where: str, value: object, keys: tuple[str, ...]) -> dict[str, Any]:
    """``value`` as an entry of a file: a mapping with ``keys[0]``, the others optional, no
    other key."""
    if not isinstance(value, dict) or keys[0] not in value:
        raise FleetFileError(f'{where} must be a mapping with {keys[0]}, got {value!r}')
    unknown = set(value) - set(keys)
    if unknown:
        raise FleetFileError(f'{where} has unknown keys {sorted(unknown)} ({", ".join(keys)})')
    return value


def _task(where: str, entry: object) -> Task:
    goal = _mapping(where, entry, ('goal_mm', 'after', 'tolerance_um'))
    after = goal.get('after')
    if after is not None and (not isinstance(after, list) or len(after) != 2 or not all(
            isinstance(v, int) and not isinstance(v, bool) and v >= 0 for v in after)):
        raise FleetFileError(f'{where}.after must be [robot, goal index], got {after!r}')
    tolerance = goal.get('tolerance_um')
    if tolerance is not None and (isinstance(tolerance, bool)
                                  or not isinstance(tolerance, int | float)
                                  or not 0.0 < tolerance < 1e4):
        raise FleetFileError(f'{where}.tolerance_um must be a number in (0, 10000), got '
                         f'{tolerance!r}')
    return Task(_pair(f'{where}.goal_mm', goal['goal_mm'], 1e-3),
                (after[0], after[1]) if after is not None else None,
                tolerance * 1e-6 if tolerance is not None else None)


def drawn_tasks(starts_m: list[tuple[float, float]], goals_per_robot: int,
                seed: int) -> list[list[Task]]:
    """A fleet's day in a micro-factory: each robot brings a part to the micro field (fine
    positioning to 3 um), then takes it to a place on the platform, and again:
    ``goals_per_robot`` goals in all, the last a place of its own (no two robots end at the same
    one): a place of the lattice away from the micro field, or beyond the lattice for more than
    39 robots."""
    rng = random.Random(f'tasks {seed}')
    places = [place for place in LATTICE_M if math.dist(place, MICRO_FIELD_CENTER_M) > 0.03]
    if len(starts_m) > len(places):
        places += [place for place in LATTICE_BEYOND_M
                   if math.dist(place, MICRO_FIELD_CENTER_M) > 0.03]
    rng.shuffle(places)
    tasks = []
    for robot in range(len(starts_m)):
        own = [places[(robot + len(starts_m) * k) % len(places)]
               for k in range(goals_per_robot)]
        goals = []
        for index in range(goals_per_robot):
            if (goals_per_robot - index) % 2 == 0:     # the last goal is a place of its own
                goals.append(Task((MICRO_FIELD_CENTER_M[0]
                                   + rng.uniform(-MICRO_GOAL_SPREAD_M, MICRO_GOAL_SPREAD_M),
                                   MICRO_FIELD_CENTER_M[1]
                                   + rng.uniform(-MICRO_GOAL_SPREAD_M, MICRO_GOAL_SPREAD_M))))
            else:
                goals.append(Task(own[index]))
        tasks.append(goals)
    return tasks


def fleet_from(robots: str, tasks: Path | None, goals_per_robot: int, seed: int,
               controller: str = 'paper') -> Fleet:
    starts, offsets, controllers = robots_from(robots, seed, controller)
    chosen = (tasks_from(tasks, len(starts)) if tasks is not None
              else drawn_tasks(starts, goals_per_robot, seed))
    return Fleet(starts, [robot_parameters(o) for o in offsets], offsets, chosen, controllers)
