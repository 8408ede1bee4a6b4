"""What a bench run's goal waits for, said as a lab reads it (omni_micro_bringup.bench_start):
what is missing named after BENCH_NOTICE_S with where to look, and the run stopped naming it
after its timeout. Stand-ins for the orchestrator's node and the graph: nothing ever comes."""

from collections.abc import Callable
from pathlib import Path

import pytest

from omni_micro_bringup import bench_start
from omni_micro_bringup.errors import RunFailed


class SilentBench:
    """An orchestrator's node that hears nothing, and a graph whose processes all live."""

    node = None
    domain_id = 42
    log_dir = Path('/tmp/runs/1')

    def __init__(self) -> None:
        self.said: list[str] = []
        self.echo: Callable[[str], None] | None = self.said.append

    def spin_for(self, seconds: float) -> None:
        """Nothing to hear."""

    def check_alive(self) -> list[str]:
        return []

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return True


@pytest.mark.parametrize('robot_missing, hint', [
    (True, "is the robot's driver publishing /joint_states in ROS_DOMAIN_ID 42"),
    (False, 'is the camera driver streaming in ROS_DOMAIN_ID 42')])
def test_what_is_missing_is_named_then_the_run_gives_up_naming_it(monkeypatch, robot_missing,
                                                                 hint):
    monkeypatch.setattr(bench_start, 'BENCH_NOTICE_S', 0.02)
    bench = SilentBench()
    missing = ["robot_1's first /robot_1/joint_states", 'a frame naming robot_0 (its code)']
    with pytest.raises(RunFailed) as failed:
        bench_start.wait_until_present(bench, bench, lambda: missing, lambda: robot_missing,
                                       timeout_s=0.1)
    both = "robot_1's first /robot_1/joint_states and a frame naming robot_0 (its code)"
    assert bench.said[0] == f'[orchestration] waiting for {both} before the goal'
    assert bench.said[1].startswith(f'[orchestration] still waiting for {both} after 0.02 s: '
                                    f'{hint}')
    assert len(bench.said) == 2
    assert str(failed.value).startswith(f'gave up waiting for {both} after 0.1 s: {hint}')
    assert str(failed.value).endswith('; logs in /tmp/runs/1')
