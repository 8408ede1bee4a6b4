"""How old each camera's captures are when its tracker publishes them, as the tracker states it
(``tracker_status``'s capture_age_s, measured from the frames' own stamps against the wall
clock: :mod:`omni_micro_vision.frame_ages`), kept as the bound a controller allows for. No rclpy.

A capture is decided on its stamp, but it can only be acted on once it has come: the servo
starts its corrections no sooner after a capture's stamp than this bound, and the other modes
count their capture timeouts from timer2's end plus it (a capture stamped at timer2's end cannot
come sooner). Frames on simulated time have no age to state: a simulated run is unchanged.
"""

from __future__ import annotations

import math


class StatedAges:
    """The oldest age each camera has stated, and the bound they make with ``own_s`` (a
    controller's own setting)."""

    def __init__(self, own_s: float = 0.0) -> None:
        self.own_s = own_s
        self._by_camera: dict[str, float] = {}

    @property
    def bound_s(self) -> float:
        return max((self.own_s, *self._by_camera.values()))

    def take(self, camera: str, said: str | None) -> float | None:
        """``camera``'s tracker states its captures' age (``said``, in seconds). Returns the new
        bound if it grew (None: it did not, or ``said`` is no age)."""
        try:
            age_s = float(said) if said is not None else math.nan
        except ValueError:
            return None
        if not (math.isfinite(age_s) and age_s >= 0.0):
            return None
        before = self.bound_s
        self._by_camera[camera] = max(age_s, self._by_camera.get(camera, 0.0))
        return self.bound_s if self.bound_s > before else None


def allowance_words(allowance_s: float) -> str:
    """What a capture timeout's line adds for the cameras' stated lateness ('' for none)."""
    return (f' and the {allowance_s:.3f} s the cameras say their captures take'
            if allowance_s > 0.0 else '')
