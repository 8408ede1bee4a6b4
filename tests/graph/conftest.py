"""Helpers for tests that start real node processes: a private domain and a probe node."""

from __future__ import annotations

import contextlib
import fcntl
import functools
import json
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import IO

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node

from omni_micro_bringup.machine_load import busy_cores
from omni_micro_bringup.processes import DomainLease, node_environment

ROOT = Path(__file__).resolve().parents[2]


class Probe:
    """An rclpy node of the test in the graph's domain, with its own context."""

    def __init__(self, domain_id: int) -> None:
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id)
        self.node = Node('test_probe', context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)

    def spin_until(self, condition: Callable[[], bool], timeout_s: float, what: str) -> None:
        deadline = time.monotonic() + timeout_s
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(f'timed out after {timeout_s} s waiting for {what}')
            self.executor.spin_once(timeout_sec=0.05)

    def spin_for(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            self.executor.spin_once(timeout_sec=0.05)

    def call(self, client, request, timeout_s: float = 10.0, resend_s: float = 2.0):
        """The service's answer. A server sees a new client's request reader before its own
        response writer has matched the client's reader: a request sent in between is answered
        into the void. So the request goes again every ``resend_s`` until answered (the calls
        tested here set parameters: asking twice changes nothing)."""
        assert client.wait_for_service(timeout_sec=timeout_s), 'service not available'
        deadline = time.monotonic() + timeout_s
        while True:
            future = client.call_async(request)
            self.executor.spin_until_future_complete(
                future, timeout_sec=min(resend_s, max(0.0, deadline - time.monotonic())))
            if future.done():
                return future.result()
            client.remove_pending_request(future)
            if time.monotonic() >= deadline:
                raise AssertionError(f'no answer from {client.srv_name} in {timeout_s} s')

    @contextlib.contextmanager
    def spinning(self) -> Iterator[None]:
        """This probe's executor, and the stand-in nodes added to it, spun on a thread of their
        own meanwhile: while the test's own code waits in another executor (the monitor's)."""
        stop = threading.Event()

        def spin() -> None:
            while not stop.is_set():
                self.executor.spin_once(timeout_sec=0.05)

        spinner = threading.Thread(target=spin, daemon=True)
        spinner.start()
        try:
            yield
        finally:
            stop.set()
            spinner.join(5.0)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


class NoDeaths:
    """The monitor's supervisor when no process of the test dies."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir

    def check_alive(self) -> list[str]:
        return []

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return True


def pause_the_robots_clock(domain_id: int) -> None:
    """dynamics_node's clock held, as the orchestration holds it before time 0: the lockstep
    then stops every message of the graph."""
    from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
    from rcl_interfaces.srv import SetParameters

    probe = Probe(domain_id)
    try:
        client = probe.node.create_client(SetParameters, '/dynamics_node/set_parameters')
        answer = probe.call(client, SetParameters.Request(parameters=[Parameter(
            name='paused', value=ParameterValue(type=ParameterType.PARAMETER_BOOL,
                                                bool_value=True))]))
        assert answer.results[0].successful
    finally:
        probe.close()


@pytest.fixture
def domain_id() -> Iterator[int]:
    with DomainLease() as domain:
        yield domain


@pytest.fixture
def probe(domain_id: int) -> Iterator[Probe]:
    probe = Probe(domain_id)
    yield probe
    probe.close()


@pytest.fixture
def start_node(domain_id: int, tmp_path: Path):
    """Start an installed node with the graph's params file; stopped with SIGINT afterwards."""
    processes: list[subprocess.Popen[bytes]] = []
    logs: list[IO[str]] = []

    def start(package: str, executable: str, *params: str) -> subprocess.Popen:
        from omni_micro_bringup.params_files import graph_params_file, resolve_executable

        argv = [str(resolve_executable(package, executable)), '--ros-args', '--params-file',
                str(graph_params_file())]
        for param in params:
            argv += ['-p', param]
        # Open for the node's whole life: closed after it has stopped, below.
        log = open(tmp_path / f'{executable}.log', 'w')  # noqa: SIM115
        logs.append(log)
        process = subprocess.Popen(argv, env=node_environment(domain_id, tmp_path), stdout=log,
                                   stderr=subprocess.STDOUT)
        processes.append(process)
        return process

    yield start
    for process in processes:
        process.send_signal(2)
    for process in processes:
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    for log in logs:
        log.close()


def run_omni_micro(*args: str, env: dict[str, str] | None = None,
               timeout: float = 300) -> subprocess.CompletedProcess:
    """The user's command, exactly as the README shows it."""
    return subprocess.run([str(ROOT / 'scripts' / 'omni-micro'), *args], cwd=ROOT,
                          capture_output=True, text=True, timeout=timeout,
                          env=env or dict(os.environ))


@pytest.fixture(scope='session')
def omni_micro():
    return run_omni_micro


@pytest.fixture
def busy_machine(request):
    """``with busy_machine(): ...`` runs the block with every core kept busy. The busy
    processes' CPU is the machine's load, not the test's: it goes into the test's report as
    ``busy_cpu_s``, which the per-test CPU limit leaves out (tests/conftest.py)."""
    def note(used_s: float) -> None:
        request.node.user_properties.append(('busy_cpu_s', round(used_s, 2)))
    return functools.partial(busy_cores, os.cpu_count() or 2, on_done=note)


# The seed of the shared Fig. 11 run (fig11_recorded); a test comparing another run with it uses
# the same.
SHARED_SEED = 3


def workers_folder(tmp_path_factory, worker_id: str) -> Path:
    """This run's temporary folder, above each xdist worker's own: what the workers share."""
    folder = tmp_path_factory.getbasetemp()
    return folder if worker_id == 'master' else folder.parent


@pytest.fixture
def shared_memory_audited_alone(tmp_path_factory, worker_id) -> Iterator[None]:
    """For a test that kills a DDS participant and then says what it left in /dev/shm: no other
    such test runs meanwhile on the other worker. A killed process's port outlives it, and the
    next participant of any graph takes it as it is (test_shared_memory_reuse.py): in one run
    the killed-node test's graph took the reuse test's killed writer's port and counted it as
    its own leftover, while the reuse test found that port's lock taken."""
    with open(workers_folder(tmp_path_factory, worker_id) / 'shared_memory.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


@pytest.fixture
def leftovers_removed(shared_memory_audited_alone) -> Iterator[None]:
    """For a test whose process dies without Fast DDS's teardown (SIGKILL, a second signal):
    afterwards, the shared-memory files that came during the test and that no living process
    holds are removed, as the orchestration removes a killed node's once its graph has stopped
    (omni_micro_bringup.shared_memory). Left there, the next participant of any graph takes a
    port as it is: beside these tests, the other worker's camera driver once failed to open
    fastrtps_port7004 (`open_and_lock_file failed`, a port these tests leave) and its frames
    never reached the tracker. Under the audit lock: a test counting what its own kill left
    must not see these go, nor these its."""
    from omni_micro_bringup.shared_memory import (
        SHM,
        shared_memory_files,
        shared_memory_holders,
        shared_memory_identities,
    )

    before = shared_memory_identities(shared_memory_files())
    yield
    came = {name for name, _ in shared_memory_identities(shared_memory_files()) - before}
    # This process's probe, closed by now, may still map a killed reader's segment (Fast DDS
    # keeps what it mapped until the process ends): that is no use of it.
    held = {name for name, pids in shared_memory_holders().items() if pids - {os.getpid()}}
    for name in sorted(came - held):
        if name.endswith('_el') and name.removesuffix('_el') in held:
            continue   # the lock of a port or segment a living process uses: its owner's
        (SHM / name).unlink(missing_ok=True)
        if name.startswith('fastrtps_port') and not name.endswith('_el'):
            (SHM / f'sem.{name}_mutex').unlink(missing_ok=True)


@pytest.fixture(scope='session')
def fig11_recorded(tmp_path_factory, worker_id) -> tuple[Path, dict]:
    """Fig. 11 through the graph as a user types it (``run --goal-mm 100,0 --rtf max --seed 3
    --record BAG --json``): its bag and its JSON summary. One run per suite, read by every test
    that only reads a plain run: each used to make its own (a graph run costs 7-10 s of CPU,
    start-up included). The xdist workers share it, as pytest-xdist's documentation shows: the
    first to need it makes it under a lock in their common temporary folder, the other waits."""
    shared = workers_folder(tmp_path_factory, worker_id)
    folder = shared / 'fig11'
    bag, summary = folder / 'bag', folder / 'summary.json'
    with open(shared / 'fig11.lock', 'w') as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not summary.exists():
            folder.mkdir(exist_ok=True)
            result = run_omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--seed',
                                    str(SHARED_SEED), '--json', '--quiet', '--record', str(bag),
                                    '--log-dir', str(folder / 'logs'))
            assert result.returncode == 0, result.stderr[-3000:]
            summary.write_text(result.stdout.strip().splitlines()[-1])
    return bag, json.loads(summary.read_text())


# The stand-ins for real drivers (tests/bench), written from those drivers' conventions.
BENCH = Path(__file__).resolve().parents[1] / 'bench'


@pytest.fixture
def bench(domain_id, tmp_path):
    """``bench(script, *args)`` starts a stand-in in the test's domain; all are stopped with
    SIGINT afterwards, as a user stops a driver."""
    processes: list[tuple[subprocess.Popen, object]] = []

    def start(script: str, *args: str) -> subprocess.Popen:
        log = open(tmp_path / f'{script}-{len(processes)}.log', 'w')  # noqa: SIM115
        process = subprocess.Popen([sys.executable, str(BENCH / script), *args],
                                   env=node_environment(domain_id, tmp_path), stdout=log,
                                   stderr=subprocess.STDOUT)
        processes.append((process, log))
        return process

    yield start
    for process, _ in processes:
        process.send_signal(signal.SIGINT)
    for process, log in processes:
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        log.close()  # type: ignore[attr-defined]
