"""The operating-system side of a run: a private DDS domain, node processes with their logs,
stopping them.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import random
import signal
import subprocess
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from omni_micro_bringup.errors import RunFailed
from omni_micro_bringup.params_files import dds_profile
from omni_micro_bringup.warm_start import WarmProcess, start_warm, warm_up

if TYPE_CHECKING:
    from omni_micro_bringup.node_spec import NodeSpec

# numpy's OpenBLAS starts a thread per core when numpy is imported, whose start-up costs a node
# process 0.1 s of CPU (scipy's, loaded by numba in dynamics_node, as much again); the nodes'
# matrices are 3 x 3, and a graph's processes already share the cores. A graph run that barely
# moves went from 4.4 s to 3.8 s of CPU. Given to the graph's processes and set by `omni-micro`
# for itself, unless the user set it.
SINGLE_THREADED_BLAS = {'OPENBLAS_NUM_THREADS': '1'}
# Fast DDS: domain ids above 232 do not fit its port scheme.
DOMAIN_RANGE = range(1, 232)
# The RTPS port scheme (the DDSI-RTPS specification, 9.6.1.1; Fast DDS's defaults): every port a
# participant of domain d binds lies in [PORT_BASE + DOMAIN_GAIN * d, + DOMAIN_GAIN).
PORT_BASE, DOMAIN_GAIN = 7400, 250


def domains_in_use() -> set[int]:
    """The DDS domains some participant on this machine is in, by the UDP ports bound."""
    ports: set[int] = set()
    for table in ('/proc/net/udp', '/proc/net/udp6'):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            local = line.split()[1]                    # address:port, in hex
            ports.add(int(local.rsplit(':', 1)[1], 16))
    return {(port - PORT_BASE) // DOMAIN_GAIN for port in ports
            if port >= PORT_BASE and (port - PORT_BASE) // DOMAIN_GAIN in DOMAIN_RANGE}



class DomainLease:
    """A ROS_DOMAIN_ID no other omni-micro run on this machine holds (an flock per id).

    ``joined``: the domain belongs to others (a real camera's or robot's drivers run in it): it
    is used as it is, not leased.
    """

    def __init__(self, requested: int | None = None, joined: bool = False) -> None:
        self.requested = requested
        self.joined = joined
        self.domain_id: int | None = None
        self._file: TextIO | None = None

    def __enter__(self) -> int:
        if self.joined:
            assert self.requested is not None, 'a joined domain is named'
            self.domain_id = self.requested
            return self.requested
        folder = Path(tempfile.gettempdir()) / f'omni-micro-domains-{os.getuid()}'
        folder.mkdir(exist_ok=True)
        candidates = ([self.requested] if self.requested is not None
                      else random.sample(list(DOMAIN_RANGE), len(DOMAIN_RANGE)))
        # Another ROS graph on this machine that knows nothing of these locks (a lab's own, a
        # test's stand-in) is seen by the ports its participants hold.
        foreign = set() if self.requested is not None else domains_in_use()
        for candidate in candidates:
            if candidate in foreign:
                continue
            handle = open(folder / f'{candidate}.lock', 'w')
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            self._file, self.domain_id = handle, candidate
            return candidate
        raise RunFailed(f'no free ROS_DOMAIN_ID among {candidates[:5]}...')

    @property
    def fileno(self) -> int | None:
        """The locked file: a child that inherits it holds the lease until it exits too (None
        for a joined domain)."""
        if self.joined:
            return None
        assert self._file is not None, 'the lease is not held'
        return self._file.fileno()

    def __exit__(self, *exc: object) -> None:
        if self._file is not None:
            self._file.close()


class NodeProcess:
    """A node's OS process, with its output kept in a log file and echoed with a prefix."""

    def __init__(self, spec: NodeSpec, argv: list[str], env: dict[str, str], log_path: Path,
                 echo: Callable[[str], None] | None, inherited_fds: tuple[int, ...] = ()) -> None:
        self.spec = spec
        self.inherited_fds = inherited_fds
        self.argv = argv
        self.env = env
        self.log_path = log_path
        self.echo = echo
        self.process: subprocess.Popen[str] | WarmProcess | None = None
        self.tail: deque[str] = deque(maxlen=20)
        self.starts = 0
        self._pump: threading.Thread | None = None
        self._ready = threading.Event()

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def role(self) -> str:
        """What the node is, whichever robot's: ``controller_node`` for ``robot_1``'s too."""
        return self.spec.executable if self.spec.namespace else self.name

    def start(self) -> None:
        self.starts += 1
        self._ready.clear()
        # Warm: forked from a zygote that has imported what is slow (warm_start).
        warm = start_warm(self.argv, self.env, self.inherited_fds)
        self.process = warm or subprocess.Popen(
            self.argv, env=self.env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT, text=True, bufsize=1, start_new_session=True,
            pass_fds=self.inherited_fds)
        # Handed to the thread that copies the process's output; it closes it at the end.
        log = open(self.log_path, 'a')  # noqa: SIM115
        log.write(f'--- start {self.starts} ({"warm" if warm else "cold"}, pid '
                  f'{self.process.pid}): {" ".join(self.argv)}\n')
        log.flush()
        self._pump = threading.Thread(target=self._copy_output, args=(self.process, log),
                                      daemon=True)
        self._pump.start()

    def _copy_output(self, process: subprocess.Popen[str], log: TextIO) -> None:
        assert process.stdout is not None
        with log:
            for line in process.stdout:
                log.write(line)
                log.flush()
                self.tail.append(line.rstrip())
                if ' ready' in line:   # every node logs "<what> ready: ..." when set up
                    self._ready.set()
                if self.echo is not None:
                    self.echo(f'[{self.name}] {line.rstrip()}')

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait until the current start of the node has logged that it is ready."""
        return self._ready.wait(timeout_s)

    def exit_code(self) -> int | None:
        return None if self.process is None else self.process.poll()

    def join_output(self) -> None:
        """Wait (briefly) until the dead process's last lines are in the log and the tail."""
        if self._pump is not None:
            self._pump.join(timeout=2.0)

    def signal(self, sig: int) -> None:
        if self.process is not None and self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.process.send_signal(sig)

    def wait(self, timeout_s: float) -> bool:
        """True once the process has exited (within ``timeout_s``)."""
        if self.process is None:
            return True
        try:
            self.process.wait(max(timeout_s, 0.0))
        except subprocess.TimeoutExpired:
            return False
        return True


# How often a stopping graph looks for processes that have exited.
_STOP_POLL_S = 0.01


def stop_together(processes: list[NodeProcess], grace_s: float = 5.0,
                  took_s: dict[str, float] | None = None) -> dict[str, int | None]:
    """SIGINT to all at once, then SIGTERM, then SIGKILL to whoever is left after each grace
    period; returns their exit codes, and puts into ``took_s`` how long each took to exit after
    the first signal. Every node stops on its first signal within a second, so the later steps
    are for a node that hangs."""
    signalled = time.monotonic()
    for sig, wait_s in ((signal.SIGINT, grace_s), (signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0)):
        alive = [p for p in processes if p.exit_code() is None]
        if not alive:
            break
        for process in alive:
            process.signal(sig)
        deadline = time.monotonic() + wait_s
        while alive and time.monotonic() < deadline:
            time.sleep(_STOP_POLL_S)
            for process in [p for p in alive if p.exit_code() is not None]:
                alive.remove(process)
                if took_s is not None:
                    took_s[process.name] = time.monotonic() - signalled
    for process in processes:
        process.join_output()
    return {process.name: process.exit_code() for process in processes}


def resident_memory_kb(processes: list[NodeProcess]) -> dict[str, int]:
    """Resident memory of each live node process (VmRSS, kB)."""
    sizes = {}
    for process in processes:
        if process.process is None or process.exit_code() is not None:
            continue
        try:
            status = Path(f'/proc/{process.process.pid}/status').read_text()
        except OSError:
            continue
        for line in status.splitlines():
            if line.startswith('VmRSS:'):
                sizes[process.name] = int(line.split()[1])
    return sizes


def new_log_dir(root: Path) -> Path:
    """A new folder for a run's logs under ``root``, named for when and by whom it started."""
    stamp = time.strftime('%Y%m%d-%H%M%S')
    folder = root / f'{stamp}-{os.getpid()}'
    suffix = 0
    while folder.exists():
        suffix += 1
        folder = root / f'{stamp}-{os.getpid()}-{suffix}'
    folder.mkdir(parents=True)
    return folder


def prepare_node_starts(log_dir: Path) -> None:
    """Have the zygote's imports done (:mod:`omni_micro_bringup.warm_start`) while the
    orchestrator prepares the run."""
    warm_up(node_environment(0, log_dir))


def node_environment(domain_id: int, log_dir: Path) -> dict[str, str]:
    """The environment of a graph's processes, with the project's Fast DDS profile unless the
    user set one (config/fastdds.xml says why), and numpy's OpenBLAS on one thread unless the
    user said otherwise (:data:`SINGLE_THREADED_BLAS`)."""
    env = {**SINGLE_THREADED_BLAS, **os.environ}
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_LOG_DIR=str(log_dir / 'ros'), PYTHONUNBUFFERED='1',
               RCUTILS_COLORIZED_OUTPUT='0')
    env.pop('ROS_LOCALHOST_ONLY', None)
    if not env.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(dds_profile())
    return env
