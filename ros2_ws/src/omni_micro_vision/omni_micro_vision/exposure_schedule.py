"""When a simulated camera's frames are due, and what each shows: every robot where it was when
the frame's exposure started, from the odometry samples as they come. No rclpy: ``camera_node``
is the adapter.

Frame k is due at k / rate seconds of simulated time, once every robot's odometry has reached
it: one robot's sample at or past it, or, for a fleet's robots (each a stream of its
own), the last of theirs. Each robot is shown between its sample before the frame's time and its
first at or after it (linear: at most a * dt^2 / 8, 4 nm at the motors' acceleration over the
20 ms grid). Frames long past when the first samples come (a camera started late) are not made
up.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from omni_micro_sim.state import RobotState
from omni_micro_vision.rendering import InView

# Stamps within this of a frame's time count as at it (a frame's time is a float division).
_STAMP_TOLERANCE_S = 1e-9


class ExposureSchedule:
    """Frames at ``rate_hz`` of simulated time of the robots carrying ``codes`` (robot i's code,
    or None for a single robot's uncoded top), fed each robot's samples in stamp order."""

    def __init__(self, rate_hz: float, codes: Sequence[int | None]) -> None:
        self.rate_hz = rate_hz
        self.codes = list(codes)
        self._samples: list[list[tuple[float, RobotState]]] = [[] for _ in self.codes]
        self._next_frame = 0

    @property
    def reached_s(self) -> float | None:
        """How far every robot's samples have come (None: some robot has sent none yet)."""
        if not all(self._samples):
            return None
        return min(samples[-1][0] for samples in self._samples)

    def on_sample(self, robot: int, now_s: float,
                  state: RobotState) -> list[tuple[int, list[InView]]]:
        """Robot ``robot``'s sample at ``now_s``: the frames now due, in order, each its number
        and the robots it shows."""
        self._samples[robot].append((now_s, state))
        reached = self.reached_s
        if reached is None:
            return []
        self._next_frame = max(self._next_frame,
                               math.floor(reached * self.rate_hz + _STAMP_TOLERANCE_S))
        due = []
        while self._next_frame / self.rate_hz <= reached + _STAMP_TOLERANCE_S:
            frame_s = self._next_frame / self.rate_hz
            due.append((self._next_frame, [InView(self._state_at(index, frame_s), code)
                                           for index, code in enumerate(self.codes)]))
            self._next_frame += 1
        self._forget_before(self._next_frame / self.rate_hz)
        return due

    def _state_at(self, robot: int, time_s: float) -> RobotState:
        """Robot ``robot`` at ``time_s``, between its sample before and its first at or after."""
        samples = self._samples[robot]
        after = next(index for index, (stamp_s, _) in enumerate(samples)
                     if stamp_s + _STAMP_TOLERANCE_S >= time_s)
        now_s, state = samples[after]
        if after == 0 or time_s >= now_s:
            return state
        before_s, before = samples[after - 1]
        share = max(0.0, (time_s - before_s) / (now_s - before_s))
        values = [a + share * (b - a) for a, b in zip(before.as_array(), state.as_array(),
                                                      strict=True)]
        values[2] = before.phi_rad + share * math.remainder(state.phi_rad - before.phi_rad,
                                                            2 * math.pi)
        return RobotState(*map(float, values))

    def _forget_before(self, time_s: float) -> None:
        """Each robot's samples the next frames can still need: its last before ``time_s`` on."""
        for samples in self._samples:
            keep = max(0, next((index for index, (stamp_s, _) in enumerate(samples)
                                if stamp_s + _STAMP_TOLERANCE_S >= time_s), len(samples)) - 1)
            del samples[:keep]
