"""The end of a commanded move, told from the wheels' joint states (the controller's timer2 counts
from it)."""

from __future__ import annotations


class MoveWatcher:
    """Tells from the wheel joint states when a commanded move is over.

    The move is over at the first state in which the driven wheel has turned by the commanded
    rotation since the command and stands still, and the wheels no longer steer (the robot
    steers before it rolls, so timer2 counts from the end of both). Wheel 2 is watched: it is
    always driven (wheel 1 may be passive and roll freely).
    """

    WATCHED_WHEEL = 1

    def __init__(self) -> None:
        self._baseline_rad: float | None = None
        self._target_rad = 0.0
        self.latest_rotations: tuple[float, ...] | None = None

    @property
    def watching(self) -> bool:
        return self._baseline_rad is not None

    def expect(self, rotation_rad: float) -> None:
        """A move that turns each wheel by ``rotation_rad`` was just commanded."""
        if self.latest_rotations is None:
            raise RuntimeError('no wheel state received yet; cannot watch a move')
        self._baseline_rad = self.latest_rotations[self.WATCHED_WHEEL]
        self._target_rad = abs(rotation_rad)

    def forget(self) -> None:
        self._baseline_rad = None

    def on_wheel_state(self, rotations_rad: tuple[float, ...], speeds_rad_s: tuple[float, ...],
                       steering_rate_rad_s: float = 0.0) -> bool:
        """Feed one wheel state (three wheels, and the steering's rate); True once, when the
        watched move is over."""
        self.latest_rotations = tuple(rotations_rad)
        if self._baseline_rad is None:
            return False
        turned = abs(rotations_rad[self.WATCHED_WHEEL] - self._baseline_rad)
        # The receiver rebuilds the profile from nanosecond stamps, so the rotation it reports
        # can differ from the commanded one in the ninth digit.
        if (turned >= self._target_rad * (1.0 - 1e-6)
                and speeds_rad_s[self.WATCHED_WHEEL] == 0.0
                and speeds_rad_s[2] == 0.0 and steering_rate_rad_s == 0.0):
            self._baseline_rad = None
            return True
        return False
