"""Frames a camera driver sent that never reached the tracker, counted from the gaps in their
stamps, and the likely cause. No rclpy.

A driver stamps its frames at a steady rate, and its CameraInfo with each frame's stamp; the
rate it sends at is read from the stamps that arrive (the shortest gaps seen since the start),
and each longer gap between two frames holds that many frames that did not. The CameraInfo is
small and comes whole where its frame does not, so its stamps give the rate even when two frames
in a row never arrive (a 3.8 MB frame through 0.5 MB segments came every third period, as
steadily as a 10 Hz driver's would). Without CameraInfo, only the frames' own gaps say it.
Losses come in stretches: one begins at a gap, and ends once ``quiet_s`` of the driver's time
passes with none. :meth:`FrameLosses.add` returns a stretch once it has lasted ``said_after_s``
(to be logged, once) and again when it ends (its final figures): how many frames of how many
since when, and what most likely lost them:

- large frames read best effort through Fast DDS's default shared-memory segments (0.5 MB): the
  writer's segment cannot hold the next frame while readers hold the last, and a best-effort
  writer drops it (a 3.8 MB mono16 frame at 30 Hz: about 7 Hz arrived). The driver's process
  needs the project's profile (4 MB segments), exported before it starts;
- the tracker itself taking longer per frame than the driver's period: its queue drops the rest;
- otherwise the transport (fragments over UDP, the driver's own queue).
"""

from __future__ import annotations

import statistics
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime

from omni_micro_common.clocks import CLOCK_MISMATCH_S

# Fast DDS's default shared-memory segment (its XML reference: segment_size, 512 KiB): a frame
# near or above it cannot be held twice by a writer left on the defaults.
DEFAULT_SEGMENT_BYTES = 512 * 1024
# How many gaps must have come, and how many of them one period long, before a loss is counted.
PERIOD_AFTER = 10
PERIOD_SEEN = 3
# Gaps within this factor of the shortest are taken as one period (a driver's stamps jitter).
PERIOD_JITTER = 1.25


@dataclass(frozen=True)
class LossStretch:
    """Frames lost since ``since_ns`` (the driver's clock): ``lost`` of ``sent``."""

    camera: str
    image_topic: str
    since_ns: int
    lost: int
    sent: int
    sent_hz: float
    cause: str
    ended: bool = False      # no frame lost for quiet_s since: these are its final figures
    said: bool = False       # said already, when it began (not to be logged again)

    @property
    def arrived_hz(self) -> float:
        return self.sent_hz * (self.sent - self.lost) / self.sent if self.sent else 0.0

    def message(self, now_ns: int | None = None) -> str:
        """One line; ``now_ns`` (this machine's clock): a stamp near it is said as a time of
        day (UTC), another as seconds of the driver's own clock."""
        if now_ns is not None and abs(now_ns - self.since_ns) < CLOCK_MISMATCH_S * 1e9:
            since = datetime.fromtimestamp(self.since_ns * 1e-9, UTC).strftime(
                '%H:%M:%S.%f')[:-3] + ' UTC'
        else:
            since = f'{self.since_ns * 1e-9:.3f} s of the driver\'s clock'
        return (f'{self.camera}: {self.lost} of {self.sent} frames from {self.image_topic} '
                f'lost since {since}: the driver sends {self.sent_hz:.1f} Hz by its stamps, '
                f'{self.arrived_hz:.1f} Hz arrive; {self.cause}')


def likely_cause(frame_bytes: int, best_effort: bool, tracking_s: float, period_s: float,
                 profile: str | None, queue_depth: int) -> str:
    """What most likely lost the frames, and what to do, in one sentence."""
    if tracking_s > period_s:
        return (f'likely cause: the tracker takes {tracking_s * 1e3:.1f} ms a frame, longer '
                f'than the driver\'s {period_s * 1e3:.1f} ms period, and its queue (depth '
                f'{queue_depth}) drops the rest: fewer cameras, binned or cropped frames, or a '
                f'lower rate')
    if best_effort and frame_bytes > DEFAULT_SEGMENT_BYTES // 2:
        export = (f'export FASTRTPS_DEFAULT_PROFILES_FILE={profile}' if profile else
                  'export FASTRTPS_DEFAULT_PROFILES_FILE=<omni_micro_common share>/config/'
                  'fastdds.xml')
        return (f'likely cause: {frame_bytes / 2**20:.1f} MB frames read best effort through '
                f'Fast DDS\'s default 0.5 MB shared-memory segments; start the driver with the '
                f'project\'s profile: {export}')
    return ('likely cause: the transport (fragments lost over UDP, or the driver\'s own queue): '
            'run the driver on this machine with the project\'s profile, or publish reliable')


@dataclass
class FrameLosses:
    """The frames of one image topic: the driver's period from their stamps, and the stretches
    of frames that never came."""

    camera: str
    image_topic: str
    quiet_s: float = 2.0       # a stretch ends after this long of the driver's time without loss
    said_after_s: float = 1.0  # and is said once it has lasted this long (or when it ends)
    _gaps_seen: int = 0
    _periods: deque[int] = field(default_factory=lambda: deque(maxlen=30))   # the shortest gaps
    _gaps: deque[int] = field(default_factory=lambda: deque(maxlen=300))     # the latest gaps
    _last_ns: int | None = None
    _info_last_ns: int | None = None
    _stretch: tuple[int, int, int] | None = None   # since, lost, sent
    _said: bool = False
    _last_loss_ns: int = 0
    lost_total: int = 0
    sent_total: int = 0

    @property
    def period_ns(self) -> float | None:
        """The driver's period by its stamps (None until PERIOD_AFTER gaps, PERIOD_SEEN of them
        one period long, have come)."""
        if self._gaps_seen < PERIOD_AFTER or len(self._periods) < PERIOD_SEEN:
            return None
        # The shortest gaps are biased short by the stamps' jitter: the latest gaps, each
        # counted in whole periods, give the rate over seconds.
        rough = statistics.median(self._periods)
        return sum(self._gaps) / sum(max(1, round(gap / rough)) for gap in self._gaps)

    def _note_gap(self, gap: int) -> None:
        """Keep the gaps within PERIOD_JITTER of the shortest: a shorter one starts anew."""
        self._gaps_seen += 1
        self._gaps.append(gap)
        shortest = min(self._periods, default=None)
        if shortest is None or gap * PERIOD_JITTER < shortest:
            self._periods.clear()
        if not self._periods or gap <= min(self._periods) * PERIOD_JITTER:
            self._periods.append(gap)

    def add_info(self, stamp_ns: int) -> None:
        """A CameraInfo stamped ``stamp_ns`` arrived: its gap to the last is the driver's."""
        last, self._info_last_ns = self._info_last_ns, stamp_ns
        if last is not None and stamp_ns > last:
            self._note_gap(stamp_ns - last)

    def add(self, stamp_ns: int, cause: Callable[[], str]) -> LossStretch | None:
        """A frame stamped ``stamp_ns`` arrived; the stretch of losses to say now, if one is
        due (``cause``: what :func:`likely_cause` says of the frames now, asked only then)."""
        last, self._last_ns = self._last_ns, stamp_ns
        if last is None or stamp_ns <= last:
            return None   # the first frame, or a driver that restarted its clock
        gap = stamp_ns - last
        period = self.period_ns
        self._note_gap(gap)
        missing = 0 if period is None else max(0, round(gap / period) - 1)
        self.sent_total += missing + 1
        self.lost_total += missing
        due: LossStretch | None = None
        if self._stretch is not None:
            since, lost, sent = self._stretch
            if missing == 0 and (stamp_ns - self._last_loss_ns) * 1e-9 > self.quiet_s:
                due = self._stretch_said(cause, ended=True)
                self._stretch, self._said = None, False
            else:
                self._stretch = (since, lost + missing, sent + missing + 1)
        elif missing:
            self._stretch = (last + round(period or gap), missing, missing + 1)
        if missing:
            self._last_loss_ns = stamp_ns
        if self._stretch is not None and not self._said \
                and (stamp_ns - self._stretch[0]) * 1e-9 >= self.said_after_s:
            due, self._said = self._stretch_said(cause), True
        return due

    def _stretch_said(self, cause: Callable[[], str], ended: bool = False) -> LossStretch:
        assert self._stretch is not None
        since, lost, sent = self._stretch
        period = self.period_ns or 0.0
        return LossStretch(self.camera, self.image_topic, since, lost, sent,
                           1e9 / period if period else 0.0, cause(), ended, self._said)
