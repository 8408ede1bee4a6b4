"""The orchestration's calls to a node's parameter service (dynamics_node's clock, a fleet
robot's tolerance, a controller's cancel), against a stand-in service: an answer lost between a
server and a new client is asked for again; a server gone is a death to report, not a silence;
a request never answered ends in one line naming it."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters
from rclpy.task import Future

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.orchestrator import Orchestrator


class Service:
    """A parameter service as a client sees it: ``lost`` requests go unanswered (their answer
    sent before the server's response writer matched), the rest answered ``successful``."""

    def __init__(self, lost: int = 0, ready: bool = True, successful: bool = True) -> None:
        self.lost, self.ready, self.successful = lost, ready, successful
        self.requests: list[Any] = []
        self.withdrawn = 0

    def call_async(self, request: Any) -> Future:
        self.requests.append(request)
        future = Future()
        if len(self.requests) > self.lost:
            future.set_result(SetParameters.Response(results=[SetParametersResult(
                successful=self.successful, reason='' if self.successful else 'out of range')]))
        return future

    def service_is_ready(self) -> bool:
        return self.ready

    def remove_pending_request(self, future: Future) -> None:
        self.withdrawn += 1


class Executor:
    def spin_until_future_complete(self, future: Future, timeout_sec: float) -> None:
        """Nothing comes that the service did not answer at once."""


class Graph:
    """A supervisor whose processes live, or whose server died (``death``: what it says)."""

    def __init__(self, death: str | None = None) -> None:
        self.death = death

    def check_alive(self) -> list[str]:
        if self.death:
            raise RunFailed(self.death)
        return []


def call(service: Any, graph: Any, **timing: float) -> Any:
    orchestration: Any = SimpleNamespace(executor=Executor())
    return Orchestrator.call(orchestration, graph, service, SetParameters.Request(),
                             'dynamics_node did not answer', **timing)


def test_an_answer_lost_is_asked_for_again_and_the_first_answer_returned():
    service = Service(lost=2)
    result = call(service, Graph(), timeout_s=5.0, resend_s=0.05)
    assert result.results[0].successful
    assert len(service.requests) == 3 and service.withdrawn == 2


def test_a_server_gone_reports_the_death_not_the_silence():
    service = Service(lost=1_000_000, ready=False)
    with pytest.raises(RunFailed, match='dynamics_node died'):
        call(service, Graph(death='dynamics_node died (exit 2)'), timeout_s=5.0)
    assert len(service.requests) == 1


def test_a_request_never_answered_ends_in_one_line_naming_it():
    service = Service(lost=1_000_000)
    with pytest.raises(RunFailed) as raised:
        call(service, Graph(), timeout_s=0.3, resend_s=0.1)
    assert str(raised.value) == 'dynamics_node did not answer within 0.3 s'
    assert 2 <= len(service.requests) <= 5     # asked again every 0.1 s, not on every spin


def test_the_clock_refused_says_why():
    orchestration: Any = SimpleNamespace(
        executor=Executor(), parameters=Service(successful=False),
        call=lambda *args, **kwargs: Orchestrator.call(orchestration, *args, **kwargs))
    graph: Any = Graph()
    with pytest.raises(RunFailed) as raised:
        Orchestrator.set_paused(orchestration, graph, False)
    assert str(raised.value) == 'could not start the clock of dynamics_node: out of range'
