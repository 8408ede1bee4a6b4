"""Same seed, same bag, byte for byte: the .mcap file and its metadata.yaml of a recorded run are
the same whatever the real-time factor, the machine's load and the process layout; another seed
gives another file; and a killed run's recovered bag is a prefix of the finished one
(docs/graph.md, "Same seed, same bag")."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import threading
from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import pytest
from bag_compare import bag_digest, stored_messages
from conftest import SHARED_SEED, Probe
from thread_stall import ready_to_stall, stall_with

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.graph import Graph, GraphResult, run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.warm_start import WARM_START_ENV
from omni_micro_common.qos import DATA_QOS


def at_simulated_time(domain_id: int, time_s: float, action: Callable[[], None]) -> None:
    """``action()`` once the graph's /clock has reached ``time_s``."""
    from rosgraph_msgs.msg import Clock

    probe = Probe(domain_id)
    try:
        now: list[Clock] = [Clock()]
        probe.node.create_subscription(Clock, '/clock', lambda msg: now.__setitem__(0, msg),
                                       DATA_QOS)
        probe.spin_until(lambda: now[0].clock.sec >= time_s, 60.0, f'/clock at {time_s} s')
        action()
    finally:
        probe.close()


def record(folder: Path, real_time_factor: float = math.inf, seed: int = SHARED_SEED,
           **options: object) -> tuple[Path, GraphResult]:
    """Fig. 11's goal, recorded: 36 periods, 20 s of simulated time. Every bag is called 'bag'
    (in a folder of its own): rosbag2 names the storage file after the bag's folder, and
    metadata.yaml says so."""
    bag = folder / 'bag'
    on_running = options.pop('on_running', None)
    result = run_graph(GraphOptions(
        goal_m=(0.1, 0.0), seed=seed, real_time_factor=real_time_factor, record=bag,
        log_dir=folder / 'logs', **options), on_running)  # type: ignore[arg-type]
    assert result.outcome == 'reached' and result.periods >= 2, result.reason
    # By construction no command arrives after its start stamp; the dynamics would say so.
    log = 'loop_container.log' if options.get('composed') else 'dynamics_node.log'
    assert 'arrived' not in (result.log_dir / log).read_text()
    return bag, result


class Reference(NamedTuple):
    bag: Path
    sim_time_s: float
    log_dir: Path


@pytest.fixture
def reference(fig11_recorded) -> Reference:
    """The suite's shared Fig. 11 run: as fast as the lockstep allows, separate processes,
    started as a user types it (`omni-micro run`), where the runs here go through
    :func:`run_graph`: the two ways in are one graph too."""
    bag, summary = fig11_recorded
    return Reference(bag, summary['sim_time_s'], Path(summary['log_dir']))


def test_same_seed_same_file_at_another_real_time_factor(reference, tmp_path):
    # Paced at 5x: the dynamics wait on the wall clock every tick, as at any finite factor
    # (the reference, as fast as it goes, is many times faster), in 4 s rather than 10 s.
    bag, result = record(tmp_path, real_time_factor=5.0)
    assert result.sim_time_s == reference.sim_time_s
    assert bag_digest(bag) == bag_digest(reference.bag)


def test_same_seed_same_file_with_both_cores_kept_busy_and_the_nodes_started_cold(
        reference, tmp_path, busy_machine, monkeypatch):
    """The reference's nodes were forked from a zygote (omni_micro_bringup.warm_start); these
    start as `ros2 run` starts them."""
    monkeypatch.setenv(WARM_START_ENV, '0')
    with busy_machine():
        bag, result = record(tmp_path)
    assert bag_digest(bag) == bag_digest(reference.bag)
    for folder, how in ((result.log_dir, 'cold'), (reference.log_dir, 'warm')):
        logs = sorted(folder.glob('*_node.log'))
        assert len(logs) == 4, logs   # dynamics, vision, controller, markers
        for log in logs:
            assert log.read_text().startswith(f'--- start 1 ({how}, pid '), log


def test_same_seed_same_file_with_the_loop_in_one_process(reference, tmp_path):
    bag, result = record(tmp_path, composed=True)
    assert (result.log_dir / 'loop_container.log').exists()
    assert not (result.log_dir / 'vision_node.log').exists()
    assert bag_digest(bag) == bag_digest(reference.bag)


def test_another_seed_another_file(reference, tmp_path):
    bag, _ = record(tmp_path, seed=SHARED_SEED + 1)
    assert bag_digest(bag) != bag_digest(reference.bag)
    # The same topics, both complete: what differs is the camera noise and what follows it.
    ours, theirs = stored_messages(bag), stored_messages(reference.bag)
    assert {topic for topic, _, _ in ours} == {topic for topic, _, _ in theirs}
    assert ours[0] == theirs[0]     # time 0's clock: the seed has changed nothing yet


def test_the_finished_bag_ends_a_fixed_simulated_time_after_the_outcome(reference):
    from omni_micro_tools.topics import BAG_TAIL_S

    messages = stored_messages(reference.bag)
    outcome_ns = round(reference.sim_time_s * 1e9)
    assert max(time for _, time, _ in messages) == outcome_ns + round(BAG_TAIL_S * 1e9)
    times = [time for _, time, _ in messages]
    assert times == sorted(times)
    # Every tick of the robot's 20 ms grid, none twice, none missing, up to the end.
    clocks = [time for topic, time, _ in messages if topic == '/clock']
    tick = 20_000_000
    assert clocks[0] <= tick
    assert clocks == list(range(clocks[0], outcome_ns + round(BAG_TAIL_S * 1e9) + 1, tick))


def test_a_killed_recorder_leaves_a_prefix_of_the_finished_bag(reference, tmp_path):
    """SIGKILL to the recorder mid-run: the run stops (a run without its bag is not what was
    asked for) and its bag is recovered, in the finished bag's order, without its last second:
    every message it keeps is the finished bag's, in the same place."""
    killers: list[threading.Thread] = []

    def kill_the_recorder_soon(graph: Graph) -> None:
        recorder = graph.process('bag_recorder').process
        assert recorder is not None
        killers.append(threading.Thread(target=at_simulated_time, args=(
            graph.domain_id, 10.0, lambda: os.kill(recorder.pid, signal.SIGKILL))))
        killers[0].start()

    # 10 s of simulated time in when it is killed, however fast the machine runs the graph (a
    # kill 2.5 s of wall time in came after 3 s of simulated time beside a busy process).
    with pytest.raises(RunFailed, match='bag_recorder'):
        record(tmp_path, real_time_factor=4.0, on_running=kill_the_recorder_soon)
    killers[0].join(timeout=60.0)   # its probe's context gone before the next test
    recovered = stored_messages(tmp_path / 'bag')
    finished = stored_messages(reference.bag)
    assert len(finished) / 4 < len(recovered) < len(finished)
    assert recovered == finished[:len(recovered)]


def test_a_recorder_stalled_for_seconds_loses_nothing(reference, tmp_path):
    """The recorder of a run in one process at full speed stalls for 3 s as the clock starts (its
    executor's thread held, as a write to a stalled disk holds it; Fast DDS's threads go on
    taking messages): the robot runs no further than the recorder's ticks allow, and the bag is
    the reference's. (Without the recorder in the lockstep the robot ran on past the 1000
    samples a writer keeps: once, beside a busy process, a bag lost 320 ticks of /odom and every
    micro capture.)"""
    stalls: list[subprocess.Popen[str]] = []
    # Started ahead: a helper started as the clock starts, on a busy machine, once stalled the
    # recorder only after this 1.6 s run had ended.
    helper = ready_to_stall(3.0)

    def stall_the_recorder(graph: Graph) -> None:
        recorder = graph.process('bag_recorder').process
        assert recorder is not None
        stalls.append(stall_with(helper, recorder.pid))

    try:
        bag, result = record(tmp_path, composed=True, on_running=stall_the_recorder)
    finally:
        if helper.poll() is None and not stalls:
            helper.kill()
            helper.wait()
    assert [stall.wait(timeout=30.0) for stall in stalls] == [0]
    assert bag_digest(bag) == bag_digest(reference.bag)
    assert result.wall_time_s > 3.0   # the robot waited for it (0.6 s without it, measured)
