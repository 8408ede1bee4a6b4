"""Node processes started warm: forked from a process that has already imported what is slow.

A node's process spends most of its start in Python's imports (numpy 0.1 s of CPU each time,
numba and the loading of its kernels another 0.6 s in dynamics_node), and a graph run starts
four to seven of them. The orchestration therefore keeps a *zygote*
(:mod:`omni_micro_bringup.zygote`) per orchestrating process: it imports those once (nothing of
ROS), then forks a child per node. The child becomes what ``ros2 run`` would have started: its
own session, the run's environment, argv and working directory, stdout and stderr
to the orchestrator's pipe, the inherited descriptors at their numbers, and the console script's
``sys.exit(main())`` run at the top level, so its exit (atexit, threads, an uncaught exception,
a signal) is the interpreter's own.

The zygote reports each child's exit status to the orchestrator, which signals the child by its
pid directly. ``OMNI_MICRO_WARM_START=0`` starts every node cold (``subprocess``), as an
executable that is not a console script of ours for this interpreter always starts
(docs/graph.md, "Nodes start warm").
"""

from __future__ import annotations

import atexit
import contextlib
import json
import os
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

from omni_micro_bringup.zygote import MESSAGE_BYTES, Launch, console_scripts

WARM_START_ENV = 'OMNI_MICRO_WARM_START'
# What the interpreter, the loader and the libraries read at import time (numpy's OpenBLAS its
# threads, numba its cache and settings, rclpy its libraries): a zygote serves the runs whose
# environment agrees with its own on these. Each child gets the whole environment of its run.
IMPORT_TIME_ENV = ('PYTHON', 'LD_', 'OPENBLAS_', 'OMP_', 'MKL_', 'NUMBA_', 'NUMPY_', 'RMW_',
                   'AMENT_', 'HOME', 'XDG_', 'VIRTUAL_ENV', 'PATH')
# A run's own, left out of the zygote's environment: a child's /proc/<pid>/environ is the
# zygote's (the run's is in its os.environ), and a stale domain there would mislead.
PER_RUN_KEYS = ('ROS_DOMAIN_ID', 'ROS_LOG_DIR', 'OMNI_MICRO_LIFELINE_FD')


class WarmProcess:
    """A forked node as the orchestrator sees it: :class:`subprocess.Popen`'s few methods the
    graph uses (``pid``, ``stdout``, ``poll``, ``wait``, ``send_signal``)."""

    def __init__(self, zygote: Zygote, pid: int, stdout_read: int) -> None:
        self._zygote = zygote
        self.pid = pid
        self.stdout = open(stdout_read, encoding='utf-8', errors='replace')  # noqa: SIM115
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            self.returncode = self._zygote.exit_code(self.pid)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self._zygote.wait_exit(self.pid, timeout) is None:
            raise subprocess.TimeoutExpired(str(self.pid), timeout or 0.0)
        return self.poll()  # type: ignore[return-value]

    def send_signal(self, sig: int) -> None:
        # Between the zygote's reaping and its report the pid is free; the kernel hands it out
        # again only after every other one (pid_max), so the signal cannot reach a stranger.
        if self.poll() is None:
            os.kill(self.pid, sig)


class Zygote:
    """One zygote process and the thread that reads its replies."""

    def __init__(self, env: dict[str, str]) -> None:
        ours, theirs = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        self._socket = ours
        # A process forked from this one shares the socket: only the owner speaks on it.
        self.owner = os.getpid()
        self.process = subprocess.Popen(
            [sys.executable, '-P', '-m', 'omni_micro_bringup.zygote', str(theirs.fileno())],
            env=env, pass_fds=(theirs.fileno(),), stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
        theirs.close()
        self._replies: list[dict] = []
        self._started: set[int] = set()
        self._exits: dict[int, int] = {}
        self._changed = threading.Condition()
        self._request_lock = threading.Lock()
        self._closed = False
        # The CPU its children's exit reports counted, until the zygote itself is reaped.
        self._children_cpu_s = 0.0
        self._reaped = False
        self._reader = threading.Thread(target=self._read_replies, daemon=True)
        self._reader.start()

    def _read_replies(self) -> None:
        while True:
            try:
                data = self._socket.recv(MESSAGE_BYTES)
            except OSError:
                data = b''
            with self._changed:
                if not data:
                    self._closed = True
                    self._changed.notify_all()
                    return
                reply = json.loads(data)
                if 'exited' in reply:
                    self._exits[reply['exited']] = reply['code']
                    if not self._reaped:
                        self._children_cpu_s += reply['cpu_s']
                        _count_cpu(reply['cpu_s'])
                else:
                    self._replies.append(reply)
                self._changed.notify_all()

    def start(self, launch: Launch, stdout_write: int, fds: tuple[int, ...]) -> int | None:
        """Fork a child; its pid, or None when the zygote cannot start this executable."""
        with self._request_lock:
            payload = json.dumps(launch.__dict__).encode()
            try:
                socket.send_fds(self._socket, [payload], [stdout_write, *fds])
            except OSError:
                return None
            with self._changed:
                self._changed.wait_for(lambda: self._replies or self._closed)
                if not self._replies:
                    return None
                pid = self._replies.pop(0).get('started')
                if pid is not None:
                    self._started.add(pid)
                return pid

    def has_children(self) -> bool:
        with self._changed:
            return bool(self._started - self._exits.keys()) and not self._closed

    def exit_code(self, pid: int) -> int | None:
        with self._changed:
            if pid in self._exits:
                return self._exits[pid]
            if self._closed:   # the zygote died: the child's status is nobody's to report
                return None if _alive(pid) else -1
            return None

    def wait_exit(self, pid: int, timeout_s: float | None) -> int | None:
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        with self._changed:
            while pid not in self._exits and not self._closed:
                left = None if deadline is None else deadline - time.monotonic()
                if left is not None and left <= 0:
                    return None
                self._changed.wait(left)
        return self.exit_code(pid)

    @property
    def usable(self) -> bool:
        alive = self.process.poll() is None
        if not alive:
            self._take_back_childrens_cpu()
        return not self._closed and alive

    def _take_back_childrens_cpu(self) -> None:
        """Once the zygote is reaped, this process's os.times() counts the CPU of every child
        it waited for (a waited-for child's rusage holds its own children's): what their
        reports counted is taken back, and later reports are not counted (a test that closed a
        zygote was charged 60.8 s of CPU in 5.8 s of wall time)."""
        with self._changed:
            if self._reaped:
                return
            self._reaped = True
            counted = self._children_cpu_s
        _count_cpu(-counted)

    def close(self) -> None:
        if os.getpid() != self.owner:
            return
        with contextlib.suppress(OSError):
            self._socket.shutdown(socket.SHUT_RDWR)
        self._socket.close()
        try:
            self.process.wait(5.0)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
        self._take_back_childrens_cpu()


_finished_cpu_s = 0.0
_finished_cpu_lock = threading.Lock()


def _count_cpu(seconds: float) -> None:
    global _finished_cpu_s
    with _finished_cpu_lock:
        _finished_cpu_s += seconds


def finished_children_cpu_s() -> float:
    """CPU used so far by the nodes this process started warm that have exited: what
    ``os.times()`` counts of the children it starts cold (the zygote, not this process, waits for
    the warm ones)."""
    with _finished_cpu_lock:
        return _finished_cpu_s


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _import_time_env(env: dict[str, str]) -> tuple[tuple[str, str], ...]:
    return tuple(sorted((k, v) for k, v in env.items() if k.startswith(IMPORT_TIME_ENV)))


# One zygote per environment its imports see; one without children is closed when another comes.
_zygotes: dict[tuple[tuple[str, str], ...], Zygote] = {}
_zygote_lock = threading.Lock()


def _zygote_for(env: dict[str, str]) -> Zygote:
    key = _import_time_env(env)
    with _zygote_lock:
        for other_key in [k for k, z in _zygotes.items() if z.owner != os.getpid()]:
            del _zygotes[other_key]   # a forked copy of this process starts its own
        zygote = _zygotes.get(key)
        if zygote is not None and not zygote.usable:
            zygote.close()
            del _zygotes[key]
            zygote = None
        if zygote is None:
            for other_key, other in list(_zygotes.items()):
                if not other.has_children():
                    other.close()
                    del _zygotes[other_key]
            zygote = _zygotes[key] = Zygote(
                {k: v for k, v in env.items() if k not in PER_RUN_KEYS})
        return zygote


@atexit.register
def _close_zygotes() -> None:
    with _zygote_lock:
        for zygote in _zygotes.values():
            zygote.close()
        _zygotes.clear()


def entry_point_of(executable: Path) -> str | None:
    """``module:function`` of an installed console script of ours run by this interpreter."""
    try:
        with open(executable, 'rb') as script:
            head = script.read(4096).decode('utf-8', 'replace')
    except OSError:
        return None
    shebang = head.splitlines()[0] if head else ''
    if shebang[2:].strip() != sys.executable:
        return None
    return console_scripts().get(executable.name)


def warm_starts(env: dict[str, str]) -> bool:
    """Whether nodes start warm: unless the run's environment, or the orchestrator's, says
    ``OMNI_MICRO_WARM_START=0``."""
    return '0' not in (env.get(WARM_START_ENV), os.environ.get(WARM_START_ENV))


def warm_up(env: dict[str, str]) -> None:
    """Start the zygote's imports now, beside the orchestrator's own preparations."""
    if warm_starts(env):
        _zygote_for(env)


def start_warm(argv: list[str], env: dict[str, str], pass_fds: tuple[int, ...],
               entry_point: str | None = None) -> WarmProcess | None:
    """Fork ``argv`` from the zygote (running ``entry_point``, by default the console script's);
    None when it must start cold."""
    if not warm_starts(env):
        return None
    entry_point = entry_point or entry_point_of(Path(argv[0]))
    if entry_point is None:
        return None
    zygote = _zygote_for(env)
    read_end, write_end = os.pipe()
    try:
        pid = zygote.start(Launch(entry_point, argv, env, os.getcwd(), list(pass_fds)),
                           write_end, pass_fds)
    finally:
        os.close(write_end)
    if pid is None:
        os.close(read_end)
        return None
    return WarmProcess(zygote, pid, read_end)
