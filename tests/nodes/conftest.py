"""In-process node tests (the fast tier): each node built with ``parameter_overrides`` inside an
rclpy context of its own, as rclpy's own tests do, with no process and no DDS traffic needed."""

from __future__ import annotations

import pytest


class Published:
    """Stands in for a publisher's ``publish``: keeps what a node sends, in order."""

    def __init__(self) -> None:
        self.messages: list[object] = []

    def __call__(self, message: object) -> None:
        self.messages.append(message)


@pytest.fixture
def spy(monkeypatch):
    """``spy(publisher)`` records what the node publishes on it instead of sending it."""

    def attach(publisher: object) -> Published:
        published = Published()
        monkeypatch.setattr(publisher, 'publish', published)
        return published
    return attach
