"""How old a camera driver's frames are when they reach the tracker, and its captures in motion
when it publishes them: measured from the frames' own stamps against the wall clock. No rclpy.

A driver stamps each frame with the system clock when it was taken; the frame then crosses the
driver, the middleware and the tracker's queue. The servo starts a correction a fixed time after
a capture's stamp, so it must know how old a capture can be when it gets it: the tracker says
what it measures (``tracker_status``, every ``window`` frames), and the controller takes it as
its bound where it exceeds its own. Frames stamped on another clock (a simulated camera, from 0)
have no age to measure against this machine's clock: nothing is said of them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

from omni_micro_common.clocks import CLOCK_MISMATCH_S
from omni_micro_common.conventions import (
    CAPTURE_AGE_KEY,
    FRAME_AGE_KEY,
    FRAME_RATE_KEY,
    IMAGE_TOPIC_KEY,
)


@dataclass
class FrameAges:
    """The ages of the latest ``window`` frames (seconds, the largest is stated).
    ``capture_after_stamp_s``: a capture in motion is stamped this long after its frame (the
    exposure's middle)."""

    capture_after_stamp_s: float = 0.0
    window: int = 30
    first_after: int = 5        # frames before the first statement (a servo waits for it)
    _frames: deque[tuple[int, int, int]] = field(init=False)   # stamp, arrived, published
    _since_said: int = field(default=0, init=False)
    _said: bool = field(default=False, init=False)

    def __post_init__(self) -> None:
        self._frames = deque(maxlen=self.window)

    def add(self, stamp_ns: int, arrived_ns: int, published_ns: int) -> bool:
        """One frame: stamped ``stamp_ns`` (its capture in motion ``published_ns`` on this
        machine's clock, after it ``arrived_ns``); whether the ages are due to be said (after
        ``first_after`` frames, then every ``window``). A frame on another clock than the wall
        clock is not counted."""
        if abs(arrived_ns - stamp_ns) > CLOCK_MISMATCH_S * 1e9:
            return False
        self._frames.append((stamp_ns, arrived_ns, published_ns))
        self._since_said += 1
        if self._since_said < (self.window if self._said else self.first_after):
            return False
        self._since_said, self._said = 0, True
        return True

    @property
    def frame_age_s(self) -> float:
        """The oldest a frame was on arrival."""
        return max(arrived - stamp for stamp, arrived, _ in self._frames) * 1e-9

    @property
    def capture_age_s(self) -> float:
        """The oldest a capture in motion was, by its own stamp, when it was published (the
        frame's transport and processing included)."""
        oldest = max(published - stamp for stamp, _, published in self._frames) * 1e-9
        return oldest - self.capture_after_stamp_s

    @property
    def frame_rate_hz(self) -> float:
        """Frames per second, by their stamps."""
        stamps = [stamp for stamp, _, _ in self._frames]
        span = (stamps[-1] - stamps[0]) * 1e-9
        return (len(stamps) - 1) / span if span > 0 else 0.0

    def values(self, image_topic: str) -> list[tuple[str, str]]:
        """The ages as a status says them."""
        return [(FRAME_AGE_KEY, f'{self.frame_age_s:.4f}'),
                (CAPTURE_AGE_KEY, f'{self.capture_age_s:.4f}'),
                (FRAME_RATE_KEY, f'{self.frame_rate_hz:.2f}'), (IMAGE_TOPIC_KEY, image_topic)]
