"""How every omni-micro node process starts, spins and stops (shared by the three packages).

SIGINT and SIGTERM both end the spin as a KeyboardInterrupt, with the context still valid, so a
node can still publish its last words (the controller's stop) before it is destroyed; rclpy's
own handlers would invalidate the context first. (rclpy's experimental EventsExecutor would be
cheaper per message, but in this rclpy it leaves the parameter services unanswered.)
"""

from __future__ import annotations

import json
import signal
import sys
from collections import Counter
from typing import Callable, TypeVar

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from omni_micro_sim.conventions import PUBLISHED_MARKER

NodeT = TypeVar('NodeT', bound=Node)


_stopping = False
_publishing = False        # inside a counted publish: an interrupt waits until it is counted
_interrupt_pending = False


class PublicationCounter:
    """Counts what a node publishes per topic; logged at shutdown, so that a bag's counts can be
    checked against what was really sent (the soak test does)."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def wrap(self, publisher):
        send = publisher.publish

        def publish(msg) -> None:
            # Sent and counted, or neither: the counts are checked against bags at shutdown.
            global _publishing, _interrupt_pending
            _publishing = True
            try:
                send(msg)
                self.counts[publisher.topic_name] += 1
            finally:
                _publishing = False
            if _interrupt_pending:
                _interrupt_pending = False
                raise KeyboardInterrupt

        publisher.publish = publish
        return publisher

    def report(self) -> str:
        return PUBLISHED_MARKER + json.dumps(dict(sorted(self.counts.items())))


def _interrupt(signum: int, frame: object) -> None:
    global _stopping, _interrupt_pending
    _stopping = True
    if _publishing:
        _interrupt_pending = True   # raised once the message is sent and counted
        return
    raise KeyboardInterrupt


def run_node(factory: Callable[[], NodeT], *, config_errors: tuple[type[Exception], ...],
             on_shutdown: Callable[[NodeT], None] | None = None,
             args: list[str] | None = None) -> None:
    """Create the node, spin it until a signal, and tear it down; a bad parameter exits 2."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    signal.signal(signal.SIGINT, _interrupt)
    signal.signal(signal.SIGTERM, _interrupt)
    node = None
    try:
        node = factory()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except RuntimeError:
        # The interrupt can land inside rclpy's C++ message conversion, which then reports a
        # conversion failure instead of the KeyboardInterrupt: that is still just a shutdown.
        if not _stopping:
            raise
    except config_errors as error:
        # A bad parameter: say which value, exit non-zero before any message is sent.
        print(f'{sys.argv[0].rsplit("/", 1)[-1]}: invalid parameter: {error}', flush=True)
        raise SystemExit(2) from None
    finally:
        if node is not None:
            if on_shutdown is not None and rclpy.ok():
                on_shutdown(node)
            counter = getattr(node, 'publication_counter', None)
            if counter is not None:
                print(counter.report(), flush=True)
            node.destroy_node()
        rclpy.try_shutdown()
