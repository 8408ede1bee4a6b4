"""The guard of several real robots on one bench: no dynamics_node sees a contact between real
robots, so the run watches where the cameras name each one and stops them all when two come
closer than the clearance allows, or when a robot driving a leg goes unnamed too long.

Two robots are too close when, from their latest captures and closing as their captures over
the last 40 ms or more say, their centres would come within ``stop_gap_m`` before a stop sent
now has taken hold: the captures' age (a frame waits for the tracker, the tracker for the
machine: on a busy one a capture arrives a quarter of a second old) and ``horizon_s`` beyond it
(the command on its way and the wheels' ramp down). A robot is unnamed while no capture of it
(still or in motion) has arrived; one that drives a leg and has turned its wheels longer than
``unnamed_s`` since it was last named is driving blind. Standing, it is no danger however long
the camera takes (a robot of the paper's rule stands still between its moves, waiting for a
capture): its wheels say so, as its driver reports them (:meth:`FleetGuard.wheels`). Without
word from its wheels (none yet, or none for longer than ``unnamed_s``), all the time unnamed
counts. Times of arrival are the caller's clock (any monotonic one), positions in the platform
frame, stamps the camera's.
"""

from __future__ import annotations

import collections
import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

from omni_micro_common.topic_names import robot_name

# Two robots' 9 mm discs touch when their centres are this close.
CONTACT_GAP_M = 9.0e-3
# Stopped once two centres would come this close: 1 mm above contact. The planner keeps them
# 12 mm apart (fleet_roadmap.CLEARANCE_M); planned runs came 11.37 mm close at the least.
STOP_GAP_M = 10.0e-3
# How far beyond now the closing is projected: the command on its way, and the wheels' 0.17 s
# ramp down (8.7 rad/s at 50 rad/s^2).
HORIZON_S = 0.2
# A robot driving a leg stopped after this long unnamed (15 frames of a 15 Hz camera).
UNNAMED_S = 1.0
# A robot seen this far from the start its plan has is somewhere else: the planner kept the
# others 12 mm from where it is not (3 mm more than the discs need, shared by two robots).
START_WITHIN_M = 1.5e-3
# Two captures further apart than this give no velocity (the robot was not followed between).
VELOCITY_SPAN_S = 0.5
# A velocity is taken over at least this long (over half a frame at 15 Hz, so there each is
# still taken from the frame before): a busy driver stamps frames when it reads them, not when
# they were exposed (usb_cam's default), so two frames read back to back come 2 ms apart by
# their stamps with a frame's travel between them. Longer, it lags a robot's 0.17 s ramp down
# (a robot parked at the planner's 12 mm was taken for one closing).
MIN_VELOCITY_SPAN_S = 0.04


@dataclass(frozen=True)
class GuardStop:
    """Why every robot is stopped: ``robots`` (indices) too close or unnamed, said in
    ``reason``."""

    kind: str        # 'proximity' or 'unnamed'
    robots: tuple[int, ...]
    reason: str


@dataclass
class _Seen:
    stamp_s: float
    x_m: float
    y_m: float
    arrived_s: float
    vx_m_s: float = 0.0
    vy_m_s: float = 0.0


@dataclass
class _Wheels:
    reported_s: float    # the latest state's arrival
    turning: bool        # a wheel or the steering moving in it


@dataclass
class FleetGuard:
    """Every robot's latest capture and whether it drives a leg; :meth:`check` says whether
    all must stop."""

    count: int
    stop_gap_m: float = STOP_GAP_M
    horizon_s: float = HORIZON_S
    unnamed_s: float = UNNAMED_S
    closest_gap_m: float = math.inf      # the closest two centres were seen, and who
    closest_pair: tuple[int, int] | None = None
    _seen: dict[int, _Seen] = field(default_factory=dict)
    # Each robot's captures of the last VELOCITY_SPAN_S, as (stamp_s, x_m, y_m).
    _recent: dict[int, collections.deque[tuple[float, float, float]]] = field(
        default_factory=dict)
    _driving_since: dict[int, float] = field(default_factory=dict)
    _wheels: dict[int, _Wheels] = field(default_factory=dict)
    # How long each robot's wheels turned since it was last named, up to its latest state.
    _turned_unnamed_s: dict[int, float] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ('stop_gap_m', 'horizon_s', 'unnamed_s'):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f'{name} must be a positive number, got {value!r}')
        if self.stop_gap_m < CONTACT_GAP_M:
            raise ValueError(f'stop_gap_m must be at least the contact gap '
                             f'{CONTACT_GAP_M * 1e3:g} mm, got {self.stop_gap_m * 1e3:g} mm')

    def saw(self, robot: int, stamp_s: float, x_m: float, y_m: float, arrived_s: float) -> None:
        """A capture of ``robot`` (still or in motion) stamped ``stamp_s``, arrived at
        ``arrived_s``; an older one than the latest is only a sign of life."""
        last = self._seen.get(robot)
        self._turned_unnamed_s[robot] = 0.0
        if last is not None and stamp_s <= last.stamp_s:
            last.arrived_s = max(last.arrived_s, arrived_s)
            return
        seen = _Seen(stamp_s, x_m, y_m, arrived_s)
        recent = self._recent.setdefault(robot, collections.deque())
        while recent and stamp_s - recent[0][0] > VELOCITY_SPAN_S:
            recent.popleft()
        base = next((r for r in reversed(recent) if stamp_s - r[0] >= MIN_VELOCITY_SPAN_S),
                    None)
        if base is not None:
            span = stamp_s - base[0]
            seen.vx_m_s, seen.vy_m_s = (x_m - base[1]) / span, (y_m - base[2]) / span
        elif last is not None and stamp_s - last.stamp_s <= VELOCITY_SPAN_S:
            seen.vx_m_s, seen.vy_m_s = last.vx_m_s, last.vy_m_s   # too close to tell anew
        recent.append((stamp_s, x_m, y_m))
        self._seen[robot] = seen
        for other, at in self._seen.items():
            if other != robot:
                gap = math.dist((x_m, y_m), _position_at(at, stamp_s))
                if gap < self.closest_gap_m:
                    self.closest_gap_m, self.closest_pair = gap, (min(robot, other),
                                                                  max(robot, other))

    @property
    def named(self) -> set[int]:
        """The robots some capture has named."""
        return set(self._seen)

    def misplaced(self, starts_m: Sequence[tuple[float, float]],
                  within_m: float = START_WITHIN_M) -> list[str]:
        """Each robot the cameras see farther than ``within_m`` from its start in ``starts_m``
        (where the plan has it), said with both places."""
        said = []
        for robot, start in enumerate(starts_m):
            seen = self._seen.get(robot)
            if seen is not None and math.dist((seen.x_m, seen.y_m), start) > within_m:
                said.append(f'{robot_name(robot)} stands at ({seen.x_m * 1e3:.2f}, '
                            f'{seen.y_m * 1e3:.2f}) mm, '
                            f'{math.dist((seen.x_m, seen.y_m), start) * 1e3:.2f} mm from its '
                            f'start ({start[0] * 1e3:g}, {start[1] * 1e3:g}) mm')
        return said

    def wheels(self, robot: int, turning: bool, arrived_s: float) -> None:
        """A state of ``robot``'s wheels from its driver, arrived at ``arrived_s``: ``turning``
        when a wheel or the steering moves in it."""
        last = self._wheels.get(robot)
        if last is not None and last.turning:
            seen = self._seen.get(robot)
            since_s = max(last.reported_s, seen.arrived_s if seen else -math.inf)
            self._turned_unnamed_s[robot] = (self._turned_unnamed_s.get(robot, 0.0)
                                             + max(arrived_s - since_s, 0.0))
        self._wheels[robot] = _Wheels(arrived_s, turning)

    def driving(self, robot: int, now_s: float, driving: bool = True) -> None:
        """``robot`` has a leg under way from ``now_s`` (or, ``driving`` False, none)."""
        if driving:
            self._driving_since.setdefault(robot, now_s)
        else:
            self._driving_since.pop(robot, None)

    def check(self, now_s: float, stamps_now_s: float | None = None) -> GuardStop | None:
        """Whether every robot must stop now (``now_s`` on the arrivals' clock;
        ``stamps_now_s``, now on the stamps' clock, for the captures' age: without it they are
        taken as fresh)."""
        for robot, since in sorted(self._driving_since.items()):
            seen = self._seen.get(robot)
            named_s = max(since, seen.arrived_s) if seen else since
            blind_s = self.turned_unnamed_s(robot, now_s, named_s)
            if blind_s > self.unnamed_s:
                last = (f'last named at ({seen.x_m * 1e3:.1f}, {seen.y_m * 1e3:.1f}) mm'
                        if seen else 'never named')
                return GuardStop('unnamed', (robot,), (
                    f'{robot_name(robot)} drove unnamed by the cameras for '
                    f'{blind_s:.2f} s (over {self.unnamed_s:g} s; {last})'))
        for a, b in itertools.combinations(sorted(self._seen), 2):
            age = 0.0 if stamps_now_s is None else max(stamps_now_s - self._later(a, b), 0.0)
            # A robot whose wheels turn goes on as its captures said however old they are; of
            # another, the velocity holds no longer than VELOCITY_SPAN_S (it may have stopped).
            # Capped for both, captures that came 0.5 s late and then stalled froze the
            # projection while a jogged robot drove on: stopped 10.5 mm apart, it touched.
            turning = {robot for robot in (a, b) if self._turning(robot, now_s)}
            ahead_s = {robot: (age if robot in turning else min(age, VELOCITY_SPAN_S))
                       + self.horizon_s for robot in (a, b)}
            gap, closing, now_gap = self.projected_gap(a, b, ahead_s, turning)
            if gap < self.stop_gap_m:
                return GuardStop('proximity', (a, b), (
                    f'{robot_name(a)} and {robot_name(b)} {now_gap * 1e3:.2f} mm apart, '
                    f'closing at {closing * 1e3:.1f} mm/s: under {self.stop_gap_m * 1e3:g} mm '
                    f'within {max(ahead_s.values()):.2f} s (9 mm discs; seen {age:.2f} s '
                    'ago)'))
        return None

    def turned_unnamed_s(self, robot: int, now_s: float, named_s: float) -> float:
        """How long ``robot``'s wheels have turned since ``named_s`` (when it was last named,
        or its leg began): all of that time without word from its wheels."""
        wheels = self._wheels.get(robot)
        if wheels is None or now_s - wheels.reported_s > self.unnamed_s:
            return now_s - named_s
        turned_s = self._turned_unnamed_s.get(robot, 0.0)
        if wheels.turning:
            turned_s += max(now_s - max(wheels.reported_s, named_s), 0.0)
        return turned_s

    def _turning(self, robot: int, now_s: float) -> bool:
        """Whether ``robot``'s wheels turn, as its driver said within ``unnamed_s``."""
        wheels = self._wheels.get(robot)
        return wheels is not None and wheels.turning and now_s - wheels.reported_s <= \
            self.unnamed_s

    def projected_gap(self, a: int, b: int, ahead_s: dict[int, float],
                      turning: set[int]) -> tuple[float, float, float]:
        """The closest robots ``a`` and ``b`` come from their latest captures (both taken to the
        later's stamp; a robot in ``turning`` however far), each moving on for its
        ``ahead_s``; how fast they close now, and how far apart they are then."""
        at = self._later(a, b)
        pa, pb = (_position_at(self._seen[r], at, math.inf if r in turning else VELOCITY_SPAN_S)
                  for r in (a, b))
        px, py = pa[0] - pb[0], pa[1] - pb[1]
        va, vb = ((self._seen[r].vx_m_s, self._seen[r].vy_m_s) for r in (a, b))
        distance = math.hypot(px, py)
        vx, vy = va[0] - vb[0], va[1] - vb[1]
        closing = -(px * vx + py * vy) / distance if distance > 0 else 0.0
        # Both move until the sooner stops, then the other alone until it stops.
        closest = distance
        start = 0.0
        for end in sorted({ahead_s[a], ahead_s[b]}):
            vx = (va[0] if ahead_s[a] > start else 0.0) - (vb[0] if ahead_s[b] > start else 0.0)
            vy = (va[1] if ahead_s[a] > start else 0.0) - (vb[1] if ahead_s[b] > start else 0.0)
            span = end - start
            speed2 = vx * vx + vy * vy
            t = 0.0 if speed2 == 0 else min(max(-(px * vx + py * vy) / speed2, 0.0), span)
            closest = min(closest, math.hypot(px + vx * t, py + vy * t))
            px, py, start = px + vx * span, py + vy * span, end
        return closest, closing, distance

    def _later(self, a: int, b: int) -> float:
        return max(self._seen[a].stamp_s, self._seen[b].stamp_s)


def _position_at(seen: _Seen, stamp_s: float,
                 holds_s: float = VELOCITY_SPAN_S) -> tuple[float, float]:
    """Where the robot was at ``stamp_s``, on from its latest capture at its velocity (for no
    longer than it holds: by default, as long as a velocity is known to)."""
    ahead = min(max(stamp_s - seen.stamp_s, 0.0), holds_s)
    return seen.x_m + seen.vx_m_s * ahead, seen.y_m + seen.vy_m_s * ahead
