"""The zygote of :mod:`omni_micro_bringup.warm_start`: ``python -P -m omni_micro_bringup.zygote
<socket fd>`` imports what the nodes need that is slow and not ROS, then forks a child per
request and reports each child's exit; the child returns from :func:`serve` and becomes the
node.

Single-threaded, because fork is only safe so; it ignores SIGINT (a terminal's Ctrl-C is for the
orchestrator, which stops the nodes in order) and ends when the orchestrator's socket closes.
"""

from __future__ import annotations

import contextlib
import ctypes
import fcntl
import importlib
import json
import os
import select
import signal
import socket
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

# The packages whose console scripts the zygote forks.
PACKAGE_PREFIX = 'omni_micro_'
MESSAGE_BYTES = 1 << 20
_PR_SET_NAME = 15   # linux/prctl.h


@dataclass(frozen=True)
class Launch:
    """What a forked child becomes (sent as JSON; its descriptors ride beside it)."""

    entry_point: str          # module:function
    argv: list[str]
    env: dict[str, str]
    cwd: str
    fd_numbers: list[int]     # where each descriptor after stdout goes in the child


_scripts: dict[str, str] | None = None


def console_scripts() -> dict[str, str]:
    global _scripts
    if _scripts is None:
        from importlib.metadata import entry_points
        _scripts = {ep.name: ep.value for ep in entry_points(group='console_scripts')
                    if ep.value.startswith(PACKAGE_PREFIX)}
    return _scripts


# What the nodes import that is slow and loads nothing of ROS: numpy, numba and the dynamics'
# compiled kernels, OpenCV, the camera, scene and controller models. rclpy and the messages are
# each child's own: loading them starts LTTng-UST's two listener threads, and Fast DDS keeps
# process-wide state, neither of which a fork should copy.
PRELOADED = ('numpy', 'cv2', 'omni_micro_sim.stepper', 'omni_micro_control.model_based',
             'omni_micro_control.servo_session', 'omni_micro_vision.rendering',
             'omni_micro_vision.tracking', 'omni_micro_vision.motion_capture')


def _preload() -> None:
    """Import :data:`PRELOADED` and load the kernels, so that each child starts with that done
    (what fails here the child meets again, and reports)."""
    for name in PRELOADED:
        with contextlib.suppress(Exception):
            importlib.import_module(name)
    with contextlib.suppress(Exception):
        importlib.import_module('omni_micro_sim.stepper').load_default_kernels()


def serve(sock: socket.socket) -> tuple[Launch, list[int]] | None:
    """Fork a child per request and report exits; returns only in a child, with what it is."""
    wake_read, wake_write = os.pipe()
    for fd in (wake_read, wake_write):
        os.set_blocking(fd, False)
    signal.signal(signal.SIGCHLD, lambda *_: None)
    signal.set_wakeup_fd(wake_write, warn_on_full_buffer=False)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    while True:
        readable, _, _ = select.select([sock.fileno(), wake_read], [], [])
        if wake_read in readable:
            with contextlib.suppress(BlockingIOError):
                os.read(wake_read, 4096)
            _report_exits(sock)
        if sock.fileno() not in readable:
            continue
        try:
            payload, fds, _, _ = socket.recv_fds(sock, MESSAGE_BYTES, 64)
        except OSError:
            payload = b''
        if not payload:
            return None
        launch = Launch(**json.loads(payload))
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            signal.set_wakeup_fd(-1)
            signal.signal(signal.SIGCHLD, signal.SIG_DFL)
            signal.signal(signal.SIGINT, signal.default_int_handler)
            for fd in (wake_read, wake_write):
                os.close(fd)
            sock.close()
            return launch, fds
        for fd in fds:
            os.close(fd)
        with contextlib.suppress(OSError):
            sock.send(json.dumps({'started': pid}).encode())


def _report_exits(sock: socket.socket) -> None:
    """Each child that has exited: its exit code, and the CPU it and its own waited-for
    children used (the orchestrator's os.times() does not count another process's children)."""
    while True:
        try:
            pid, status, usage = os.wait4(-1, os.WNOHANG)
        except ChildProcessError:
            return
        if pid == 0:
            return
        with contextlib.suppress(OSError):
            sock.send(json.dumps({'exited': pid, 'code': os.waitstatus_to_exitcode(status),
                                  'cpu_s': usage.ru_utime + usage.ru_stime}).encode())


def become(launch: Launch, fds: list[int]) -> Callable[[], int | str | None]:
    """Make this forked child the process ``ros2 run`` would have started; its entry point."""
    os.setsid()
    os.chdir(launch.cwd)
    # Out of the way of the numbers they must end at, then there, then nothing else open.
    high = [fcntl.fcntl(fd, fcntl.F_DUPFD, 1024) for fd in fds]
    for fd in fds:
        os.close(fd)
    stdout, *inherited = high
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    os.close(devnull)
    os.dup2(stdout, 1)
    os.dup2(stdout, 2)
    for fd, number in zip(inherited, launch.fd_numbers, strict=True):
        os.dup2(fd, number)
    keep = {0, 1, 2, *launch.fd_numbers}
    for fd in _open_fds():
        if fd not in keep:
            with contextlib.suppress(OSError):
                os.close(fd)
    sys.stdout = open(1, 'w', buffering=1, closefd=False)  # noqa: SIM115
    sys.stderr = open(2, 'w', buffering=1, closefd=False)  # noqa: SIM115
    os.environ.clear()
    os.environ.update(launch.env)
    sys.argv = list(launch.argv)
    _name_process(launch.argv)
    module, function = launch.entry_point.split(':')
    return getattr(importlib.import_module(module), function)


# The name glibc keeps for the program (rcutils names a node's ROS log file by it), held here
# for the process's life: setproctitle writes the title over the memory it pointed into.
_invocation_name: ctypes.Array[ctypes.c_char] | None = None


def _name_process(argv: list[str]) -> None:
    """Name the process as the started script is named: its command line (``ps aux``, ``htop``,
    ``pgrep -f``) the executable and its arguments, as ``ros2 run`` gives them, where the fork
    would show the zygote's (``python -P -m omni_micro_bringup.zygote 4``); its kernel name
    (``top``, ``ps -e``, ``pgrep``) and glibc's program name (its ROS log file's) the
    executable's."""
    global _invocation_name
    import setproctitle

    setproctitle.setproctitle(' '.join(argv))
    with contextlib.suppress(OSError, AttributeError, ValueError):
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(_PR_SET_NAME, Path(argv[0]).name.encode()[:15], 0, 0, 0)
        _invocation_name = ctypes.create_string_buffer(argv[0].encode())
        address = ctypes.addressof(_invocation_name)
        ctypes.c_void_p.in_dll(libc, 'program_invocation_name').value = address
        ctypes.c_void_p.in_dll(libc, 'program_invocation_short_name').value = (
            address + len(argv[0].encode()) - len(Path(argv[0]).name.encode()))


def _open_fds() -> list[int]:
    return [int(name) for name in os.listdir('/proc/self/fd')]


def main() -> None:
    sock = socket.socket(fileno=int(sys.argv[1]))
    # setproctitle finds the command line's memory by walking from the environment, which a
    # child replaces before it names itself: found here, while both are as exec left them.
    import setproctitle
    setproctitle.setproctitle(setproctitle.getproctitle())
    _preload()
    child = serve(sock)
    if child is None:
        # Its owner closed the socket and waits for this exit. Nothing here needs tearing
        # down (no output, no files, its children reported): the interpreter's own teardown
        # of everything preloaded took 0.2 s of every command's end.
        os._exit(0)
    entry = become(*child)
    sys.exit(entry())


if __name__ == '__main__':
    main()
