"""The platform as the fleet planner reserves it: a roadmap of places and the straight moves
between them, and which moves pass too close to each other for two robots at once.

The roadmap is a square grid of ``pitch_m`` anchored on the micro field's centre (so that the
micro work platform is a place), inside the platform less a robot radius, plus every start and
goal, each linked to its nearest grid place. A *segment* is a move between two linked places
or a stay at one (a segment of length 0); two segments *conflict* when they pass closer than
``clearance_m``: two robots on them at once could touch.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from omni_micro_common.conventions import (
    MICRO_FIELD_CENTER_M,
    PLATFORM_CENTER_M,
    PLATFORM_SIZE_M,
)
from omni_micro_sim.parameters import RobotParameters

# The chassis is a 9 mm disc (section 3.4; omni_micro_sim.parameters).
ROBOT_DIAMETER_M = 2.0 * RobotParameters.chassis_radius_m
# Centres are kept 12 mm apart: 3 mm more than touching, 1.5 mm per robot against the farthest
# a robot driven by the paper's rule strayed from its straight leg: 0.50 mm in 100 crossing runs
# of 4 robots with wheel offsets of up to 3 deg, long legs driven through points 24 mm apart
# (omni_micro_studies.fleet_twin; measured by omni-micro fleet-study; 0.07 mm without offsets).
CLEARANCE_M = 12.0e-3
# Distances are compared to the clearance this much short of it: places one pitch apart may be
# a rounding error closer than it in floating point, and are side by side all the same.
ROUNDING_M = 1e-9
# Parallel lanes one pitch apart are then usable side by side.
PITCH_M = CLEARANCE_M


class RoadmapError(ValueError):
    """A place the robots cannot be: off the platform."""


@dataclass(frozen=True)
class Roadmap:
    places_m: np.ndarray                 # (P, 2): grid places first, then starts and goals
    neighbours: tuple[tuple[int, ...], ...]
    segments: dict[tuple[int, int], int]   # (u, v) with u <= v (a stay: u == v) -> id
    conflicts: tuple[frozenset[int], ...]  # per segment id: the ids within clearance of it
    clearance_m: float

    def place_of(self, point_m: tuple[float, float]) -> int:
        """The roadmap place at ``point_m`` (a start or a goal given to :func:`build_roadmap`)."""
        distances = np.hypot(*(self.places_m - np.asarray(point_m)).T)
        index = int(np.argmin(distances))
        if distances[index] > 1e-9:
            raise RoadmapError(f'{point_m} is not a place of this roadmap')
        return index

    def segment(self, u: int, v: int) -> int:
        return self.segments[(u, v) if u <= v else (v, u)]


def platform_bounds_m(margin_m: float) -> tuple[float, float, float, float]:
    """x_min, x_max, y_min, y_max of where a robot's centre may be with ``margin_m`` to spare."""
    half_x, half_y = PLATFORM_SIZE_M[0] / 2.0, PLATFORM_SIZE_M[1] / 2.0
    return (PLATFORM_CENTER_M[0] - half_x + margin_m, PLATFORM_CENTER_M[0] + half_x - margin_m,
            PLATFORM_CENTER_M[1] - half_y + margin_m, PLATFORM_CENTER_M[1] + half_y - margin_m)


def check_on_platform(point_m: tuple[float, float], what: str) -> None:
    """A robot's whole disc must be on the platform (the macro camera sees no further)."""
    x_min, x_max, y_min, y_max = platform_bounds_m(ROBOT_DIAMETER_M / 2.0)
    x, y = point_m
    if not (math.isfinite(x) and math.isfinite(y)
            and x_min <= x <= x_max and y_min <= y <= y_max):
        raise RoadmapError(
            f'{what} ({x * 1e3:g}, {y * 1e3:g}) mm is off the platform: a robot\'s centre must '
            f'be within x {x_min * 1e3:g}..{x_max * 1e3:g} mm, y {y_min * 1e3:g}..'
            f'{y_max * 1e3:g} mm (its 9 mm disc on the 150 mm platform)')


def _grid_axis(low: float, high: float, anchor: float, pitch: float) -> np.ndarray:
    first = math.ceil((low - anchor) / pitch - 1e-9)
    last = math.floor((high - anchor) / pitch + 1e-9)
    return anchor + pitch * np.arange(first, last + 1)


def build_roadmap(points_m: list[tuple[float, float]], *, pitch_m: float = PITCH_M,
                  clearance_m: float = CLEARANCE_M, lanes_m: float | None = None) -> Roadmap:
    """The grid, plus ``points_m`` (starts and goals) each linked to its nearest grid place.

    ``lanes_m``: a second square grid of that pitch over the platform, anchored alike, whose
    places off the first grid are each linked to their two nearest places of it. Robots
    resting on the lanes' places leave room between them to pass along the lanes."""
    x_min, x_max, y_min, y_max = platform_bounds_m(ROBOT_DIAMETER_M / 2.0)
    places: list[tuple[float, float]] = []
    links: list[set[int]] = []
    _add_grid(places, links, (x_min, x_max, y_min, y_max), pitch_m)
    fixed = np.array(places)
    if lanes_m is not None:
        lanes = _add_grid(places, links, (x_min, x_max, y_min, y_max), lanes_m)
        for lane in lanes:
            if lane >= len(fixed):
                for nearest in np.argsort(np.hypot(*(fixed - places[lane]).T))[:2]:
                    links[lane].add(int(nearest))
                    links[int(nearest)].add(lane)
        fixed = np.array(places)
    for point in points_m:
        distances = np.hypot(*(fixed - np.asarray(point)).T)
        nearest = int(np.argmin(distances))
        if distances[nearest] <= 1e-9:     # a grid place: that place, as given
            places[nearest] = (float(point[0]), float(point[1]))
            continue
        if point in places:
            continue
        places.append((float(point[0]), float(point[1])))
        links.append({nearest})
        links[nearest].add(len(places) - 1)
    places_m = np.array(places, dtype=float)
    pairs = sorted({(u, u) for u in range(len(places))}
                   | {(min(u, v), max(u, v)) for u in range(len(places)) for v in links[u]})
    segments = {pair: index for index, pair in enumerate(pairs)}
    ends = np.array(pairs)
    starts_m, ends_m = places_m[ends[:, 0]], places_m[ends[:, 1]]
    # Only segments whose midpoints are near can conflict: measured for those pairs alone.
    from scipy.spatial import cKDTree  # here: the command line's help loads no scipy

    middles = (starts_m + ends_m) / 2.0
    reach = clearance_m + float(np.max(np.hypot(*(ends_m - starts_m).T)))
    candidates = np.array(sorted(cKDTree(middles).query_pairs(reach)), dtype=int).reshape(-1, 2)
    distances = pair_distances(starts_m[candidates[:, 0]], ends_m[candidates[:, 0]],
                               starts_m[candidates[:, 1]], ends_m[candidates[:, 1]])
    close: list[set[int]] = [{index} for index in range(len(pairs))]
    for a, b in candidates[distances < clearance_m - ROUNDING_M]:
        close[a].add(int(b))
        close[b].add(int(a))
    conflicts = tuple(frozenset(near) for near in close)
    return Roadmap(places_m, tuple(tuple(sorted(link)) for link in links), segments,
                   conflicts, clearance_m)


def _add_grid(places: list[tuple[float, float]], links: list[set[int]],
              bounds: tuple[float, float, float, float], pitch: float) -> list[int]:
    """Add a square grid of ``pitch`` within ``bounds`` anchored on the micro field, each place
    linked to its four neighbours; a place already there is used as it is. Returns the grid's
    place indices."""
    x_min, x_max, y_min, y_max = bounds
    xs = _grid_axis(x_min, x_max, MICRO_FIELD_CENTER_M[0], pitch)
    ys = _grid_axis(y_min, y_max, MICRO_FIELD_CENTER_M[1], pitch)
    existing = np.array(places).reshape(-1, 2)
    indices = []
    for x, y in np.round(np.array([(x, y) for x in xs for y in ys]), 12):
        distances = np.hypot(*(existing - (x, y)).T)
        if len(distances) and distances.min() <= 1e-9:
            indices.append(int(np.argmin(distances)))
            continue
        places.append((float(x), float(y)))
        links.append(set())
        indices.append(len(places) - 1)
    columns = len(ys)
    for index in range(len(indices)):
        row, column = divmod(index, columns)
        for neighbour in ([index + 1] if column + 1 < columns else []) + (
                [index + columns] if row + 1 < len(xs) else []):
            links[indices[index]].add(indices[neighbour])
            links[indices[neighbour]].add(indices[index])
    return indices


def distances_to(roadmap: Roadmap, goal: int) -> dict[int, int]:
    """Steps from each place to ``goal`` along the roadmap's links."""
    distances = {goal: 0}
    queue = deque([goal])
    while queue:
        place = queue.popleft()
        for near in roadmap.neighbours[place]:
            if near not in distances:
                distances[near] = distances[place] + 1
                queue.append(near)
    return distances


def point_segment_distance(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distances of points to segments, elementwise over the leading axes."""
    along = ends - starts
    length2 = np.sum(along * along, axis=-1)
    safe = np.where(length2 > 0.0, length2, 1.0)
    t = np.clip(np.sum((points - starts) * along, axis=-1) / safe, 0.0, 1.0)
    t = np.where(length2 > 0.0, t, 0.0)
    nearest = starts + t[..., None] * along
    return np.hypot(*np.moveaxis(points - nearest, -1, 0))


def _cross(o: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return ((a[..., 0] - o[..., 0]) * (b[..., 1] - o[..., 1])
            - (a[..., 1] - o[..., 1]) * (b[..., 0] - o[..., 0]))


def pair_distances(a0: np.ndarray, a1: np.ndarray, b0: np.ndarray, b1: np.ndarray
                   ) -> np.ndarray:
    """Closest distances between segments a0[i]-a1[i] and b0[i]-b1[i] (2-D), elementwise."""
    distance = np.minimum.reduce([
        point_segment_distance(a0, b0, b1), point_segment_distance(a1, b0, b1),
        point_segment_distance(b0, a0, a1), point_segment_distance(b1, a0, a1)])
    # Proper crossings (each segment's ends on either side of the other) touch: distance 0.
    crossing = ((_cross(b0, b1, a0) * _cross(b0, b1, a1) < 0.0)
                & (_cross(a0, a1, b0) * _cross(a0, a1, b1) < 0.0))
    return np.where(crossing, 0.0, distance)


def segment_distances(starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """(m, m) closest distances between the segments ``starts[i]``-``ends[i]``."""
    shape = (len(starts), len(starts), 2)
    a0, a1 = (np.broadcast_to(end[:, None, :], shape) for end in (starts, ends))
    b0, b1 = (np.broadcast_to(end[None, :, :], shape) for end in (starts, ends))
    return pair_distances(a0, a1, b0, b1)
