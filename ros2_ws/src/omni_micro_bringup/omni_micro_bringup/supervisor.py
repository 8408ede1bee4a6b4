"""What the orchestrator's node needs of whoever runs the processes (graph.Graph): it watches
the ROS side and leaves the processes to its supervisor, so the dependency runs one way."""

from __future__ import annotations

from pathlib import Path
from typing import Protocol


class Supervisor(Protocol):
    """What the orchestrator needs of whoever runs the processes (graph.Graph): it watches the ROS
    side and leaves the processes to its supervisor, so the dependency runs one way."""

    log_dir: Path

    def check_alive(self) -> list[str]:
        """Raise if a node died for good; return the names of nodes just respawned."""
        ...

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        """Wait until the node's current process says it is ready."""
        ...
