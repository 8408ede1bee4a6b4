"""Frames a camera driver sent that never reached the tracker, counted from the gaps in their
stamps, and the likely cause. No rclpy.

A driver publishes a CameraInfo with each frame's stamp. It is small and comes where its
3.8 MB frame does not, so each CameraInfo whose frame never came is a frame lost, and their
stamps give the rate sent, however irregular (a 3.8 MB frame through 0.5 MB segments came every
third period, as steadily as a 10 Hz driver's would). Without CameraInfo, the rate is read from
the frames' own stamps (the commonest of their shorter gaps) and each longer gap holds
that many frames that never came: a driver losing two frames of three every time then looks
like one sending at a third of the rate.
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

import bisect
import statistics
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime

from omni_micro_common.clocks import CLOCK_MISMATCH_S

# Fast DDS's default shared-memory segment (its XML reference: segment_size, 512 KiB): a frame
# near or above it cannot be held twice by a writer left on the defaults.
DEFAULT_SEGMENT_BYTES = 512 * 1024
# How many gaps must have come, and how many of them near one period, before a loss is counted.
PERIOD_AFTER = 10
PERIOD_SEEN = 3
# Gaps within this factor of each other are taken as one period (a driver's stamps jitter).
PERIOD_JITTER = 1.25
# CameraInfo stamps kept waiting for their frame (10 s at 30 Hz).
PENDING_LIMIT = 300
# Stamps of frames known sent, kept to reach back past the 300 CameraInfo stamps' span.
SENT_KEPT = 600


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
    """What most likely lost the frames, and what to do, in one sentence (both causes when
    both hold: a busy machine's tracker slower than a driver on the defaults)."""
    causes = []
    if best_effort and frame_bytes > DEFAULT_SEGMENT_BYTES // 2:
        export = (f'export FASTRTPS_DEFAULT_PROFILES_FILE={profile}' if profile else
                  'export FASTRTPS_DEFAULT_PROFILES_FILE=<omni_micro_common share>/config/'
                  'fastdds.xml')
        causes.append(f'{frame_bytes / 2**20:.1f} MB frames read best effort through Fast '
                      f'DDS\'s default 0.5 MB shared-memory segments; start the driver with '
                      f'the project\'s profile: {export}')
    if tracking_s > period_s:
        causes.append(f'the tracker takes {tracking_s * 1e3:.1f} ms a frame, longer than the '
                      f'driver\'s {period_s * 1e3:.1f} ms period, and its queue (depth '
                      f'{queue_depth}) drops the rest: fewer cameras, binned or cropped frames, '
                      f'or a lower rate')
    if not causes:
        causes.append('the transport (fragments lost over UDP, or the driver\'s own queue): '
                      'run the driver on this machine with the project\'s profile, or publish '
                      'reliable')
    return ('likely cause: ' if len(causes) == 1 else 'likely causes: ') + '; and '.join(causes)


@dataclass
class FrameLosses:
    """The frames of one image topic: the driver's period from their stamps, and the stretches
    of frames that never came."""

    camera: str
    image_topic: str
    quiet_s: float = 2.0       # a stretch ends after this long of the driver's time without loss
    said_after_s: float = 1.0  # and is said once it has lasted this long (or when it ends)
    _gaps: deque[int] = field(default_factory=lambda: deque(maxlen=300))     # the latest gaps
    _last_ns: int | None = None
    _infos: deque[int] = field(default_factory=lambda: deque(maxlen=300))    # CameraInfo stamps
    # The stamps of frames known sent, in order: a CameraInfo's or a frame's, whichever came.
    _sent: list[int] = field(default_factory=list)
    # CameraInfo stamps whose frame has not come (yet), and frames whose CameraInfo has not.
    _pending: dict[int, None] = field(default_factory=dict)
    _early: deque[int] = field(default_factory=lambda: deque(maxlen=30))
    _stretch: tuple[int, int, int] | None = None   # since, lost, sent
    _said: bool = False
    _last_loss_ns: int = 0
    lost_total: int = 0
    sent_total: int = 0

    @property
    def period_ns(self) -> float | None:
        """The driver's period by its stamps (None until enough have come).

        With CameraInfo, the frames known sent over their span: one CameraInfo for every frame
        sent, however irregularly, or its frame where that CameraInfo was lost (best effort:
        one of 54 on a busy machine). Else the commonest of the frames' shorter gaps (not the
        shortest: a driver that stamps a late frame when it gets to it sends the next one soon
        after) gives it roughly, and the latest gaps, each counted in whole periods of that,
        over seconds."""
        if len(self._infos) >= PERIOD_SEEN:
            first, last = self._infos[0], self._infos[-1]
            sent = (bisect.bisect_right(self._sent, last)
                    - bisect.bisect_left(self._sent, first))
            return (last - first) / (sent - 1)
        if len(self._gaps) < PERIOD_AFTER:
            return None
        ordered = sorted(self._gaps)

        def near(gap: int) -> tuple[int, int]:
            return (bisect.bisect_left(ordered, gap / PERIOD_JITTER),
                    bisect.bisect_right(ordered, gap * PERIOD_JITTER))

        # The most common gap among the shorter half: a late frame's catch-up is rarer.
        low, high = max((near(gap) for gap in ordered[:len(ordered) // 2 + 1]),
                        key=lambda bounds: bounds[1] - bounds[0])
        if high - low < PERIOD_SEEN:
            return None
        rough = statistics.median(ordered[low:high])
        return sum(self._gaps) / sum(max(1, round(gap / rough)) for gap in self._gaps)

    def add_info(self, stamp_ns: int) -> None:
        """A CameraInfo stamped ``stamp_ns`` arrived: a frame of that stamp was sent."""
        if self._infos and stamp_ns <= self._infos[-1]:
            if stamp_ns < self._infos[-1]:
                self._infos.clear()   # a driver that restarted its clock
                self._sent.clear()
            return
        self._infos.append(stamp_ns)
        self._known_sent(stamp_ns)
        if stamp_ns in self._early:
            self._early.remove(stamp_ns)
        else:
            self._pending[stamp_ns] = None
            if len(self._pending) > PENDING_LIMIT:   # frames that never come at all: bounded
                del self._pending[next(iter(self._pending))]

    def _known_sent(self, stamp_ns: int) -> None:
        at = bisect.bisect_left(self._sent, stamp_ns)
        if at < len(self._sent) and self._sent[at] == stamp_ns:
            return
        self._sent.insert(at, stamp_ns)
        if len(self._sent) > SENT_KEPT:
            del self._sent[0]

    def _missing_by_info(self, stamp_ns: int, first: bool) -> list[int]:
        """The frames sent before this one (their CameraInfo came) that never came; none
        before the first frame (the image reader may match the driver after the info's)."""
        if stamp_ns in self._pending:
            del self._pending[stamp_ns]
        else:
            self._early.append(stamp_ns)
        older = [stamp for stamp in self._pending if stamp < stamp_ns]
        for stamp in older:
            del self._pending[stamp]
        return [] if first else older

    def add(self, stamp_ns: int, cause: Callable[[], str]) -> LossStretch | None:
        """A frame stamped ``stamp_ns`` arrived; the stretch of losses to say now, if one is
        due (``cause``: what :func:`likely_cause` says of the frames now, asked only then)."""
        last, self._last_ns = self._last_ns, stamp_ns
        self._known_sent(stamp_ns)
        # Kept before any CameraInfo came too: the first frame can come before its own.
        lost_by_info = self._missing_by_info(stamp_ns, last is None)
        by_info = lost_by_info if self._infos else None
        if last is None or stamp_ns <= last:
            return None   # the first frame, or a driver that restarted its clock
        gap = stamp_ns - last
        period = self.period_ns
        self._gaps.append(gap)
        if by_info is not None:
            missing = len(by_info)
        else:
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
            first_lost = by_info[0] if by_info else last + round(period or gap)
            self._stretch = (first_lost, missing, missing + 1)
        if missing:
            self._last_loss_ns = stamp_ns
        if self._stretch is not None and not self._said \
                and (stamp_ns - self._stretch[0]) * 1e-9 >= self.said_after_s:
            due, self._said = self._stretch_said(cause), True
        return due

    def summary(self) -> str:
        """The frames that came of those the driver sent (by their stamps), in one line: the
        whole run's (the first frame is counted here, not in ``sent_total``)."""
        return (f'{self.camera}: {self.sent_total - self.lost_total + 1} frames from '
                f'{self.image_topic} came of the {self.sent_total + 1} the driver sent by their '
                f'stamps ({self.lost_total} lost)')

    def _stretch_said(self, cause: Callable[[], str], ended: bool = False) -> LossStretch:
        assert self._stretch is not None
        since, lost, sent = self._stretch
        period = self.period_ns or 0.0
        return LossStretch(self.camera, self.image_topic, since, lost, sent,
                           1e9 / period if period else 0.0, cause(), ended, self._said)
