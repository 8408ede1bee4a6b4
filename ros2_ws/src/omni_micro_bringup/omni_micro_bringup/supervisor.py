"""What the orchestrator's node needs of whoever runs the processes (graph.Graph): it watches
the ROS side and leaves the processes to its supervisor, so the dependency runs one way; and a
supervisor that notes the nodes it respawned for a fleet's coordinator to bring back
(:class:`RestartsNoted`)."""

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


class RestartsNoted:
    """The graph as the coordinator's waits watch it: a node respawned during any of them is
    noted, and brought back where every status read so far has been handled."""

    def __init__(self, graph: Supervisor) -> None:
        self.graph = graph
        self.log_dir = graph.log_dir
        self.restarted: list[str] = []

    def check_alive(self) -> list[str]:
        restarted = self.graph.check_alive()
        self.restarted += restarted
        return restarted

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return self.graph.wait_ready(name, timeout_s)
