"""Lockstep: how far the simulated robot may run ahead of the nodes that close its loop.

Webots' ``synchronization TRUE`` and CARLA's synchronous mode wait for every controller each
step; this does the same with a bounded lead. Every node that takes part reports on
``/lockstep`` after each input it has fully handled (every output it causes already published):

- ``processed_ns``: every sample stamped up to here is handled (absent from a node that reads
  no odometry: a tracker, waited for only through the frames it has still to handle);
- ``captures_ns``: the first and last capture stamp it published while doing so (a camera, a
  tracker);
- ``capture_handled_ns``: the latest capture stamp it has handled (a controller);
- ``motion_ns`` and ``motion_handled_ns``: the same for the captures of the moving robot, apart
  from the stationary ones (a camera publishes them later than their stamp, so the two kinds
  interleave out of stamp order). The robot waits for them only once some node reports
  ``motion_handled_ns`` (a controller that acts on them: the servo); watchers do not draw them;
- ``frames_ns``: the first and last image stamp it published (a rendering camera), and
  ``frame_handled_ns``: the latest image stamp up to which it has handled every camera's frame
  (a tracker; a recorder that must keep every frame);
- ``command_ns``: the stamp of the last command it published, and ``command_lead_ns``, how long
  after their capture its moves start (a controller);
- ``command_handled_ns``: the stamp of the command it has just handled, and with it
  ``capture_handled_ns``: a *watcher*, a node that reads no odometry but must see every capture
  and command before time goes on (markers_node, so that what it draws for a tick never depends
  on which message reached it first). A watcher holds time at most one period past a capture
  it has not handled, and holds it still while a command it has not handled is on its way;
- ``outcome_ns``: the stamp of the last goal's end it published (a controller), and
  ``outcome_handled_ns``: the end of a goal it has just handled, every goal that end gives
  already taken by its controller (a *coordinator*, who hands several robots their goals as
  others' end). Once a coordinator has reported, time stands still while an end it has not
  handled is on its way, so that the next goals start from the same simulated time every run;
- ``recorded_ns``: every per-tick sample stamped up to here is in its bag (a recorder). The robot
  runs at most ``RECORDER_LEAD_TICKS`` past it: a writer keeps the last few samples of a stream
  (omni_micro_common.qos), and a recorder further behind than that lost the oldest for good (a
  composed run at full speed beside busy processes recorded /odom with 320 ticks missing).

A plain "processed up to" stamp is not enough: a capture, a command and a report travel on
different topics, and DDS orders messages per writer only. So the robot also waits until the
captures a camera reported are handled by the controller, and until the commands a controller
reported have arrived, and until the frames a camera reported are handled by their tracker
(whose captures then count as a camera's). With a lead of at most ``command_lead_s``, a command
can then never arrive after its start stamp and no sample is ever dropped, whatever the
machine's load: the run is a function of its inputs and the seed, not of the CPU.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from omni_micro_common.errors import LockstepError

# Reports travel here as diagnostic_msgs/DiagnosticStatus: name = the node, values = the fields.
ACK_TOPIC = '/lockstep'
ACK_MESSAGE = 'lockstep'
# The most the robot runs ahead of the slowest node taking part (two 20 ms ticks); a controller
# whose moves start sooner after their capture (command_lead_s) lowers it to that.
DEFAULT_MAX_LEAD_S = 0.04
# A replay that keeps pace with nodes (omni-micro replay --sync) sends no more than this many
# stamped messages beyond what the slowest has reported handled.
REPLAY_SYNC_WINDOW = 10
# How far the robot may run ahead of a recorder's ``recorded_ns``. The shallowest history a
# recorded stream keeps is a status's 10 (omni_micro_common.qos; captures keep 100, the per-tick
# streams 1000), and a controller publishes a status per period, 0.15 s at the shortest: in 10
# ticks (0.2 s at the default grid) no writer drops a sample the recorder has not had. (500
# ticks lost 9 of a run's 39 statuses while the recorder was stopped.)
RECORDER_LEAD_TICKS = 10

_FIELDS = ('processed_ns', 'capture_first_ns', 'capture_last_ns', 'capture_handled_ns',
           'command_ns', 'command_lead_ns', 'frame_first_ns', 'frame_last_ns',
           'frame_handled_ns', 'command_handled_ns', 'motion_first_ns', 'motion_last_ns',
           'motion_handled_ns', 'outcome_ns', 'outcome_handled_ns', 'recorded_ns')
# What a watcher reports before it has handled any capture or command.
NOTHING_HANDLED_NS = -1


@dataclass(frozen=True)
class Ack:
    """One node's report: see the module docstring for each field."""

    node: str
    processed_ns: int | None
    captures_ns: tuple[int, int] | None = None
    capture_handled_ns: int | None = None
    command_ns: int | None = None
    command_lead_ns: int | None = None
    frames_ns: tuple[int, int] | None = None
    frame_handled_ns: int | None = None
    command_handled_ns: int | None = None
    motion_ns: tuple[int, int] | None = None
    motion_handled_ns: int | None = None
    outcome_ns: int | None = None
    outcome_handled_ns: int | None = None
    recorded_ns: int | None = None

    @property
    def watcher(self) -> bool:
        return self.command_handled_ns is not None

    def to_values(self) -> list[tuple[str, str]]:
        values = [] if self.processed_ns is None else [('processed_ns', str(self.processed_ns))]
        for kind, span in (('capture', self.captures_ns), ('frame', self.frames_ns),
                           ('motion', self.motion_ns)):
            if span is not None:
                values += [(f'{kind}_first_ns', str(span[0])), (f'{kind}_last_ns', str(span[1]))]
        for name in ('capture_handled_ns', 'command_ns', 'command_lead_ns', 'frame_handled_ns',
                     'command_handled_ns', 'motion_handled_ns', 'outcome_ns',
                     'outcome_handled_ns', 'recorded_ns'):
            value = getattr(self, name)
            if value is not None:
                values.append((name, str(value)))
        return values

    @classmethod
    def from_values(cls, node: str, values: Iterable[tuple[str, str]]) -> Ack:
        """Raises LockstepError naming a missing, unknown or non-integer field."""
        fields: dict[str, int] = {}
        for key, text in values:
            if key not in _FIELDS:
                raise LockstepError(f'lockstep report of {node!r}: unknown field {key!r}')
            try:
                fields[key] = int(text)
            except ValueError:
                raise LockstepError(f'lockstep report of {node!r}: {key} must be a whole '
                                    f'number of nanoseconds, got {text!r}') from None
        if not {'processed_ns', 'frame_handled_ns', 'command_handled_ns',
                'outcome_handled_ns', 'recorded_ns'} & set(fields):
            raise LockstepError(f'lockstep report of {node!r} has none of processed_ns, '
                                f'frame_handled_ns, command_handled_ns, outcome_handled_ns '
                                f'and recorded_ns')
        if ('command_handled_ns' in fields) != ('capture_handled_ns' in fields) \
                and 'processed_ns' not in fields:
            raise LockstepError(f'lockstep report of {node!r}: a watcher reports '
                                f'command_handled_ns and capture_handled_ns together')
        spans: dict[str, tuple[int, int] | None] = {}
        for kind in ('capture', 'frame', 'motion'):
            first, last = fields.get(f'{kind}_first_ns'), fields.get(f'{kind}_last_ns')
            if (first is None) != (last is None):
                raise LockstepError(f'lockstep report of {node!r}: {kind}_first_ns and '
                                    f'{kind}_last_ns come together')
            spans[kind] = None if first is None or last is None else (first, last)
        return cls(node, fields.get('processed_ns'), spans['capture'],
                   fields.get('capture_handled_ns'), fields.get('command_ns'),
                   fields.get('command_lead_ns'), spans['frame'], fields.get('frame_handled_ns'),
                   fields.get('command_handled_ns'), spans['motion'],
                   fields.get('motion_handled_ns'), fields.get('outcome_ns'),
                   fields.get('outcome_handled_ns'), fields.get('recorded_ns'))


class LockstepGate:
    """Decides how far simulated time may go, from the reports of the nodes that take part.

    Parameters
    ----------
    nodes : names of the nodes that take part (reports of others are ignored).
    period_ns : the robot's grid period.
    max_lead_ns : the most the robot may run ahead of the slowest node; a controller's
        ``command_lead_ns`` lowers it. Never less than one period (the robot must be able to
        publish the sample the nodes wait for).
    """

    RECEIVED_COMMANDS_KEPT = 256

    def __init__(self, nodes: Sequence[str], period_ns: int, max_lead_ns: int) -> None:
        if period_ns <= 0:
            raise LockstepError(f'the grid period must be > 0 ns, got {period_ns}')
        if max_lead_ns < 0:
            raise LockstepError(f'lockstep lead must be >= 0, got {max_lead_ns} ns')
        self.nodes = tuple(dict.fromkeys(name for name in nodes if name))
        self.period_ns = period_ns
        self.max_lead_ns = max_lead_ns
        self._lead_ns = max_lead_ns
        # How long after its capture a move starts (the controller says): a capture, or a frame
        # that may become one, holds the robot exactly that far ahead of it, not a whole tick
        # less, so that a camera can render the next frame while the last is being tracked.
        self._move_lead_ns = max_lead_ns
        self._processed: dict[str, int] = {}
        self._capture_handled: dict[str, int] = {}
        self._awaited_commands: dict[str, int] = {}
        self._pending_captures: list[tuple[int, int]] = []
        self._motion_handled: dict[str, int] = {}
        self._pending_motion: list[tuple[int, int]] = []
        self._frame_handled: dict[str, int] = {}
        self._pending_frames: list[tuple[int, int]] = []
        self._received_commands: deque[int] = deque(maxlen=self.RECEIVED_COMMANDS_KEPT)
        # Watchers (see the module docstring): the captures each has handled up to, the
        # commands each has handled, and the captures some watcher has still to handle.
        self._watched_up_to: dict[str, int] = {}
        self._watched_commands: dict[str, deque[int]] = {}
        self._unwatched_captures: list[tuple[int, int]] = []
        # Nodes known to report without processed_ns: a reset does not wait for their stamp
        # (a watcher reports when a throttled sample comes, maybe beyond the lead).
        self._reads_no_odometry: set[str] = set()
        # Goals' ends (controllers' outcome_ns) and who hands out the next goals (coordinators,
        # known from their first report on, as what they handled, across resets).
        self._awaited_outcomes: dict[str, int] = {}
        self._handled_outcomes: dict[str, set[int]] = {}   # all kept: one per goal
        self._coordinators: set[str] = set()
        self._recorded: dict[str, int] = {}   # each recorder's recorded_ns
        # reachable_ns() of the reports so far: the dynamics asks after every report of every
        # robot's nodes, and a fleet's gates mostly have nothing new (None: work it out again).
        self._reachable: int | float | None = None
        self.reset(0)

    @property
    def enabled(self) -> bool:
        return bool(self.nodes)

    @property
    def lead_ticks(self) -> int:
        return max(1, self._lead_ns // self.period_ns)

    def reset(self, now_ns: int) -> None:
        """Every node counts as caught up at ``now_ns`` (start, or resuming after a pause in
        which a node may have been replaced: a new process knows nothing of the old one's)."""
        self._reachable = None
        self._processed = dict.fromkeys(
            (node for node in self.nodes if node not in self._reads_no_odometry), now_ns)
        self._capture_handled.clear()
        self._awaited_commands.clear()
        self._pending_captures.clear()
        self._motion_handled.clear()
        self._pending_motion.clear()
        self._frame_handled.clear()
        self._pending_frames.clear()
        self._watched_up_to.clear()
        self._watched_commands.clear()
        self._unwatched_captures.clear()
        # A coordinator's handled ends are kept: a controller reports its last end again.
        self._awaited_outcomes.clear()
        self._recorded = dict.fromkeys(self._recorded, now_ns)

    def on_ack(self, ack: Ack) -> None:
        if ack.node not in self.nodes:
            return
        self._reachable = None
        if ack.processed_ns is not None:
            self._processed[ack.node] = ack.processed_ns
        else:
            # It reads no odometry: its frames to handle hold time back, not its stamp.
            self._processed.pop(ack.node, None)
            self._reads_no_odometry.add(ack.node)
        if ack.captures_ns is not None:
            self._pending_captures.append(ack.captures_ns)
            if not self._capture_handled:
                # Nobody who handles captures has reported (yet): keep a bounded memory.
                del self._pending_captures[:-self.RECEIVED_COMMANDS_KEPT]
            self._unwatched_captures.append(ack.captures_ns)
            if not self._watched_up_to:
                del self._unwatched_captures[:-self.RECEIVED_COMMANDS_KEPT]
        if ack.motion_ns is not None:
            self._pending_motion.append(ack.motion_ns)
            if not self._motion_handled:
                del self._pending_motion[:-self.RECEIVED_COMMANDS_KEPT]
        if ack.motion_handled_ns is not None:
            self._motion_handled[ack.node] = ack.motion_handled_ns
        if ack.outcome_ns is not None:
            self._awaited_outcomes[ack.node] = ack.outcome_ns
        if ack.recorded_ns is not None:
            self._recorded[ack.node] = ack.recorded_ns
        if ack.outcome_handled_ns is not None:
            self._coordinators.add(ack.node)
            self._handled_outcomes.setdefault(ack.node, set()).add(ack.outcome_handled_ns)
        if ack.watcher:
            assert ack.command_handled_ns is not None
            self._watched_up_to[ack.node] = max(
                self._watched_up_to.get(ack.node, NOTHING_HANDLED_NS),
                NOTHING_HANDLED_NS if ack.capture_handled_ns is None else ack.capture_handled_ns)
            self._watched_commands.setdefault(
                ack.node, deque(maxlen=self.RECEIVED_COMMANDS_KEPT)).append(
                    ack.command_handled_ns)
            return
        if ack.frames_ns is not None:
            self._pending_frames.append(ack.frames_ns)
            if not self._frame_handled:
                del self._pending_frames[:-self.RECEIVED_COMMANDS_KEPT]
        if ack.capture_handled_ns is not None:
            self._capture_handled[ack.node] = ack.capture_handled_ns
        if ack.frame_handled_ns is not None:
            self._frame_handled[ack.node] = ack.frame_handled_ns
        if ack.command_ns is not None:
            self._awaited_commands[ack.node] = ack.command_ns
        if ack.command_lead_ns is not None:
            self._lead_ns = min(self.max_lead_ns, max(0, ack.command_lead_ns))
            self._move_lead_ns = max(0, ack.command_lead_ns)

    def on_command(self, stamp_ns: int) -> None:
        """A command stamped ``stamp_ns`` reached the robot."""
        self._reachable = None
        self._received_commands.append(stamp_ns)

    def waiting_for(self) -> str | None:
        """What holds time back right now, for a log line (None: nothing beyond the lead)."""
        missing = [f'{node} command at {ns} ns' for node, ns in self._awaited_commands.items()
                   if ns not in self._received_commands]
        if missing:
            return ', '.join(missing)
        unwatched = [f'{watcher} to handle the command at {ns} ns'
                     for watcher, handled in self._watched_commands.items()
                     for ns in self._awaited_commands.values() if ns not in handled]
        if unwatched:
            return ', '.join(unwatched)
        unhandled = self._unhandled_outcomes()
        if unhandled:
            return ', '.join(unhandled)
        if self._watched_up_to and self._unwatched_captures:
            watcher = min(self._watched_up_to, key=self._watched_up_to.__getitem__)
            return f'{watcher} to handle the capture at {self._unwatched_captures[0][0]} ns'
        if self._frame_handled and self._pending_frames:
            tracker = min(self._frame_handled, key=self._frame_handled.__getitem__)
            return f'{tracker} to handle the frame at {self._pending_frames[0][0]} ns'
        if self._capture_handled:
            handler = min(self._capture_handled, key=self._capture_handled.__getitem__)
            pending = [first for first, last in self._pending_captures
                       if last > self._capture_handled[handler]]
            if pending:
                return f'{handler} to handle the capture at {min(pending)} ns'
        if self._motion_handled:
            handler = min(self._motion_handled, key=self._motion_handled.__getitem__)
            pending = [first for first, last in self._pending_motion
                       if last > self._motion_handled[handler]]
            if pending:
                return f'{handler} to handle the capture in motion at {min(pending)} ns'
        slowest = min(self._processed, key=self._processed.__getitem__, default=None)
        return None if slowest is None else f'{slowest} at {self._processed[slowest]} ns'

    def _unhandled_outcomes(self) -> list[str]:
        return [f'{coordinator} to handle the end of a goal at {ns} ns'
                for coordinator in self._coordinators
                for ns in self._awaited_outcomes.values()
                if ns not in self._handled_outcomes.get(coordinator, ())]

    def reachable_ns(self) -> int | float:
        """The latest grid time the robot may reach now (``inf`` when nobody takes part)."""
        if self._reachable is None:
            self._reachable = self._work_out_reachable_ns()
        return self._reachable

    def _work_out_reachable_ns(self) -> int | float:
        if not self.nodes:
            return math.inf
        if any(ns not in self._received_commands for ns in self._awaited_commands.values()):
            return -math.inf   # a command is on its way: wait for it, whatever its stamp
        if any(ns not in handled for handled in self._watched_commands.values()
               for ns in self._awaited_commands.values()):
            return -math.inf   # ... and for every watcher to have it
        if self._unhandled_outcomes():
            return -math.inf   # a goal's end: the next goals start from it, whatever the load
        reachable = min(self._processed.values(), default=math.inf)
        if not math.isinf(reachable):
            reachable += self.lead_ticks * self.period_ns
        if self._recorded:
            reachable = min(reachable, min(self._recorded.values())
                            + RECORDER_LEAD_TICKS * self.period_ns)
        if self._frame_handled:
            handled = min(self._frame_handled.values())
            self._pending_frames = [f for f in self._pending_frames if f[1] > handled]
            if self._pending_frames:
                # A frame not yet tracked may become a capture: as for a capture.
                reachable = min(reachable, min(first for first, _ in self._pending_frames)
                                + self._move_lead_ns)
        if self._capture_handled:
            handled = min(self._capture_handled.values())
            self._pending_captures = [c for c in self._pending_captures if c[1] > handled]
            if self._pending_captures:
                # The move a capture causes starts a lead after it: no further than that.
                reachable = min(reachable, min(first for first, _ in self._pending_captures)
                                + self._move_lead_ns)
        if self._motion_handled:
            handled = min(self._motion_handled.values())
            self._pending_motion = [c for c in self._pending_motion if c[1] > handled]
            if self._pending_motion:
                # The same for a capture in motion: its correction starts after it.
                reachable = min(reachable, min(first for first, _ in self._pending_motion)
                                + self._move_lead_ns)
        if self._watched_up_to:
            watched = min(self._watched_up_to.values())
            self._unwatched_captures = [c for c in self._unwatched_captures if c[1] > watched]
            if self._unwatched_captures:
                # A watcher must have a capture before any later sample can reach it.
                reachable = min(reachable, min(first for first, _ in self._unwatched_captures)
                                + self.period_ns)
        if math.isinf(reachable):
            return -math.inf   # only trackers take part, and no camera: nothing to go by
        return reachable
