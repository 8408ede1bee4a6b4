"""What a node published, per topic, printed at shutdown: a bag's counts can then be checked
against what was really sent (the soak does)."""

from __future__ import annotations

import json
from collections import Counter
from typing import Any

from omni_micro_common.conventions import PUBLISHED_MARKER


class PublicationCounter:
    """Counts what a node publishes per topic; logged at shutdown, so that a bag's counts can be
    checked against what was really sent (the soak test does)."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def wrap(self, publisher: Any) -> Any:
        send = publisher.publish
        topic = publisher.topic_name

        def publish(msg: object) -> None:
            send(msg)
            self.counts[topic] += 1

        publisher.publish = publish
        return publisher

    def report(self) -> str:
        return PUBLISHED_MARKER + json.dumps(dict(sorted(self.counts.items())))
