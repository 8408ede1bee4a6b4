"""What the orchestration reads of the bag recorder (:class:`RecorderWatch`): whether it records,
how far it has received every stream it must keep, and a failure to write, which stops the run."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from diagnostic_msgs.msg import DiagnosticStatus

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.supervisor import Supervisor
from omni_micro_common.qos import STATUS_QOS
from omni_micro_common.topic_names import RECORDER_STATUS_TOPIC
from omni_micro_tools.topics import RECEIVED_UP_TO_KEY


class RecorderWatch:
    """The recorder's status as ``node`` reads it, spun by ``spin_for`` while waiting."""

    def __init__(self, node: Any, spin_for: Callable[[float], None]) -> None:
        self.spin_for = spin_for
        self.ready = False
        self.received_s = -1.0   # how far the recorder has every tick topic
        self.failure: str | None = None
        node.create_subscription(DiagnosticStatus, RECORDER_STATUS_TOPIC, self._on_status,
                                 STATUS_QOS)

    def _on_status(self, msg: DiagnosticStatus) -> None:
        self.ready = self.ready or msg.message == 'recording'
        values = {item.key: item.value for item in msg.values}
        if RECEIVED_UP_TO_KEY in values:
            self.received_s = max(self.received_s, float(values[RECEIVED_UP_TO_KEY]))
        if msg.level == DiagnosticStatus.ERROR:
            self.failure = values.get('reason', msg.message)

    def check(self) -> None:
        """A recorder that cannot write (a full disk) stops the run: a run without its bag is
        not what was asked for."""
        if self.failure is not None:
            raise RunFailed(f'bag_recorder {self.failure}; the run was stopped and the '
                            'bag keeps what was written (omni-micro bag-recover BAG --out DIR, '
                            'on a disk with room, makes it readable)')

    def wait_past(self, graph: Supervisor, stamp_s: float, timeout_s: float) -> None:
        """Until the recorder has every tick topic (simulated, the markers too) up to ``stamp_s``:
        stopped sooner, a recorder behind a busy graph would lose what was on its way."""
        deadline = time.monotonic() + timeout_s
        while self.received_s < stamp_s:
            graph.check_alive()
            self.check()
            if time.monotonic() > deadline:
                raise RunFailed(f'the recorder received the robot\'s streams only up to '
                                f'{self.received_s:.3f} s, not {stamp_s:.3f} s, within '
                                f'{timeout_s:g} s')
            self.spin_for(0.05)
