"""A process's main thread held still for some seconds while its other threads go on: how a node
whose executor blocks (a write to a stalled disk, a long garbage collection) looks to the graph.

SIGSTOP is not that: it stops every thread, Fast DDS's receiving threads too, and Fast DDS then
regenerates the stopped process's shared-memory port, which can leave writers of other processes
sending into the removed one for good (docs/reliability.md). Here a helper process traces the
one thread (ptrace PTRACE_SEIZE and PTRACE_INTERRUPT, Linux) and lets it go after the stall: a
tracer that is not the node's parent, so the orchestrator's waits never see the trace stop, and
the kernel lets the thread go should the helper die first.

Run as a script it is the helper: ``python thread_stall.py SECONDS``, then the pid on its
standard input; it prints ``stalled`` once the thread has stopped. Started ahead
(:func:`ready_to_stall`), it stalls a node within a write of the moment asked, not an
interpreter's start later (on a busy machine, longer than a short run lasts).
"""

from __future__ import annotations

import ctypes
import os
import subprocess
import sys
import time

PTRACE_DETACH = 17
PTRACE_SEIZE = 0x4206
PTRACE_INTERRUPT = 0x4207
WAIT_ALL = 0x40000000    # __WALL: the stop of a thread that is not a child


def ready_to_stall(seconds: float) -> subprocess.Popen[str]:
    """The helper, started and waiting for the pid of the process to stall for ``seconds``."""
    return subprocess.Popen([sys.executable, __file__, str(seconds)], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)


def stall_with(helper: subprocess.Popen[str], pid: int) -> subprocess.Popen[str]:
    """Stop ``pid``'s main thread through a helper of :func:`ready_to_stall` (returns once it
    is stopped); wait on the returned helper to know it has been let go (exit code 0)."""
    assert helper.stdin is not None and helper.stdout is not None
    helper.stdin.write(f'{pid}\n')
    helper.stdin.flush()
    said = helper.stdout.readline().strip()
    if said != 'stalled':
        helper.wait()
        raise RuntimeError(f'could not stall the main thread of {pid}: {said!r}')
    return helper


def _ptrace(request: int, thread_id: int) -> None:
    libc = ctypes.CDLL(None, use_errno=True)
    libc.ptrace.argtypes = [ctypes.c_long, ctypes.c_long, ctypes.c_void_p, ctypes.c_void_p]
    libc.ptrace.restype = ctypes.c_long
    if libc.ptrace(request, thread_id, None, None) != 0:
        error = ctypes.get_errno()
        raise OSError(error, f'ptrace {request:#x} of thread {thread_id}: {os.strerror(error)}')


def _stall(thread_id: int, seconds: float) -> None:
    _ptrace(PTRACE_SEIZE, thread_id)
    _ptrace(PTRACE_INTERRUPT, thread_id)
    _, status = os.waitpid(thread_id, WAIT_ALL)
    if not os.WIFSTOPPED(status):
        print(f'thread {thread_id} did not stop (wait status {status:#x})', flush=True)
        sys.exit(1)
    print('stalled', flush=True)
    time.sleep(seconds)
    _ptrace(PTRACE_DETACH, thread_id)


if __name__ == '__main__':
    try:
        _stall(int(sys.stdin.readline()), float(sys.argv[1]))
    except OSError as failure:
        print(failure, flush=True)
        sys.exit(1)
