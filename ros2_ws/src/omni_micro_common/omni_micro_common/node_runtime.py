"""How every omni-micro node process starts, spins and stops (shared by every package).

``run_node`` is the rclpy examples' main (spin; KeyboardInterrupt / ExternalShutdownException;
destroy the node; ``try_shutdown``) with one difference. rclpy's own SIGINT handler shuts the
context down before ``spin`` returns, after which the controller could no longer publish its
last words (the stop command). So SIGINT and SIGTERM are handled here, and, as rclpy's handler
does, ours wakes the executor through a guard condition. Python runs a signal handler only
between bytecodes, never while the executor waits in C, so the C-level wake-up fd
(``signal.set_wakeup_fd``) is watched by a thread that triggers the guard condition. Without it
a node with nothing to do (no /clock running) ignored Ctrl-C until a message happened to come.

The same thread watches the orchestrator's lifeline (``OMNI_MICRO_LIFELINE_FD``): the read end of
a pipe whose write end only the orchestrator holds. When the orchestrator dies, however it dies,
the kernel closes that end, the read returns end-of-file, and the node stops as on SIGTERM.

A second signal during the shutdown ends the process at once (exit code 130).
"""

from __future__ import annotations

import contextlib
import cProfile
import faulthandler
import os
import select
import signal
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

import rclpy
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from omni_micro_common.conventions import LIFELINE_ENV
from omni_micro_common.errors import ParameterError, ParamsFileError
from omni_micro_common.parameter_checks import check_given_parameters, params_files
from omni_micro_common.params import load_params_file

NodeT = TypeVar('NodeT', bound=Node)

# Set to a folder: each node writes its cProfile statistics there at exit (the benchmark does).
PROFILE_ENV = 'OMNI_MICRO_PROFILE'
# Which rclpy executor spins a node: 'events' (rclpy.experimental.EventsExecutor, the default:
# its wait is C++, not a wait set rebuilt in Python on every wake-up) or 'single'
# (SingleThreadedExecutor).
EXECUTOR_ENV = 'OMNI_MICRO_EXECUTOR'
# The EventsExecutor's spin_once is woken by a message or a timer only (not by wake() from
# another thread): a signal is seen within this long.
SPIN_TIMEOUT_S = 0.05
EXECUTORS = ('events', 'single')


def make_executor() -> Any:
    """The executor of :data:`EXECUTOR_ENV`."""
    kind = os.environ.get(EXECUTOR_ENV, 'events')
    if kind not in EXECUTORS:
        raise ParameterError(f'{EXECUTOR_ENV} must be one of {", ".join(EXECUTORS)}, '
                             f'got {kind!r}')
    if kind == 'single':
        return SingleThreadedExecutor()
    from rclpy.experimental import EventsExecutor

    return EventsExecutor()


class _Shutdown:
    """Whether the node was asked to stop, and how often (set by the signal handler)."""

    def __init__(self) -> None:
        self.signals = 0

    @property
    def requested(self) -> bool:
        return self.signals > 0

    def on_signal(self, signum: int, frame: object) -> None:
        self.signals += 1
        if self.signals > 1:
            raise KeyboardInterrupt   # a second Ctrl-C: no more last words


class _Waker(threading.Thread):
    """Wakes the executor when a signal arrives, and turns the lifeline's end into SIGTERM."""

    def __init__(self, wake: Callable[[], None], lifeline_fd: int | None) -> None:
        super().__init__(name='omni-micro-waker', daemon=True)
        self._wake = wake
        self._signal_read, signal_write = os.pipe()
        os.set_blocking(signal_write, False)
        self._signal_write = signal_write
        self._previous_fd = signal.set_wakeup_fd(signal_write, warn_on_full_buffer=False)
        self._lifeline_fd = lifeline_fd
        self.orphaned = False      # the orchestrator died: leave at once, no draining

    def run(self) -> None:
        watched = [self._signal_read]
        if self._lifeline_fd is not None:
            watched.append(self._lifeline_fd)
        while True:
            try:
                ready, _, _ = select.select(watched, [], [])
            except (OSError, ValueError):
                return   # the pipe was closed: the process is on its way out
            for fd in ready:
                try:
                    data = os.read(fd, 512)
                except OSError:
                    return
                if fd == self._lifeline_fd and not data:
                    # The orchestrator is gone: stop as if it had sent SIGTERM. The signal
                    # handler runs in the main thread; its wake-up byte brings us back here.
                    self.orphaned = True
                    watched.remove(fd)
                    silence_output()
                    os.kill(os.getpid(), signal.SIGTERM)
            self._wake()

    def close(self) -> None:
        signal.set_wakeup_fd(self._previous_fd)


def silence_output() -> None:
    """Send this process's stdout and stderr to /dev/null from now on.

    An orphaned node's output went to its dead orchestrator's pipes, where every write raises
    BrokenPipeError: the first one in a shutdown hook or in the counts printed at the end
    aborted the teardown before the fast exit (:func:`_exit_now`), and the interpreter's own
    teardown then kept the graph alive up to 1.2 s after its orchestrator was killed, on an
    idle machine (the recorder, whose last line is printed after its bag is closed, every
    time)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(OSError, ValueError):
                stream.flush()   # what is buffered was for the pipe: lost either way
        os.dup2(devnull, 1)
        os.dup2(devnull, 2)
    finally:
        os.close(devnull)


def lifeline_fd() -> int | None:
    """The inherited read end of the orchestrator's lifeline, if this process has one."""
    text = os.environ.get(LIFELINE_ENV)
    if not text:
        return None
    try:
        fd = int(text)
        os.fstat(fd)
    except (ValueError, OSError):
        print(f'{LIFELINE_ENV}={text!r} is not an open file descriptor; ignored',
              file=sys.stderr, flush=True)
        return None
    return fd


# -- parameters a node was given ---------------------------------------------------------------


@dataclass(frozen=True)
class NodeComponent:
    """How to run one node class: what makes it, which errors mean a bad parameter, its last
    words, and (a node that only listens) its drain count (see :func:`run_node`). Every node
    module of the graph has one as ``COMPONENT``: its ``main`` runs it alone, the container
    (:mod:`omni_micro_common.container`) runs several in one process."""

    factory: Callable[..., Node]
    config_errors: tuple[type[Exception], ...] = ()
    on_shutdown: Callable[[Any], None] | None = None
    drain: Callable[[Any], int] | None = None


@dataclass(frozen=True)
class Hosted:
    """A component in a process: ``node_args`` are its own ROS arguments (``--ros-args ...``),
    or None for the process's command line (a node alone in its process)."""

    component: NodeComponent
    node_args: list[str] | None = None
    label: str = ''          # how errors name it (a container hosts several)


def run_node(factory: Callable[[], NodeT], *, config_errors: tuple[type[Exception], ...],
             on_shutdown: Callable[[NodeT], None] | None = None,
             args: list[str] | None = None, domain_id: int | None = None,
             drain: Callable[[NodeT], int] | None = None) -> None:
    """Create the node, spin it until a signal (or the lifeline's end), and tear it down.

    ``on_shutdown`` runs on every way out once the node exists (the context may already be shut
    down if something else ended it: check ``rclpy.ok()`` before publishing). The process then
    ends with code 0. A bad parameter (one of ``config_errors``) exits 2 naming it; a second
    signal during the shutdown exits 130 at once.

    ``drain``, for a node that only listens and may lag behind the graph: a count of messages
    it has handled. After a signal it keeps handling what is queued until the count stops
    moving for ``DRAIN_IDLE_S`` (at most ``DRAIN_MAX_S``), so that its last words are the
    graph's last state.
    """
    run_component(NodeComponent(factory, config_errors, on_shutdown, drain), args=args,
                  domain_id=domain_id)


def run_component(component: NodeComponent, *, args: list[str] | None = None,
                  domain_id: int | None = None) -> None:
    """:func:`run_node` of a node module's ``COMPONENT``: its ``main``."""
    run_components([Hosted(component)], args=args, domain_id=domain_id)


def run_components(hosted: list[Hosted], *, args: list[str] | None = None,
                   domain_id: int | None = None) -> None:
    """:func:`run_node` for several nodes in one process, spun by one executor: each is made with
    its own ROS arguments, in the order given, and stopped in that order. A bad parameter of any
    exits 2 before any of them runs."""
    # A crash in the C layers (rmw, DDS) prints the Python stack it came from into the log.
    faulthandler.enable(all_threads=True)
    # `kill -USR1 <pid>` prints where every thread of a node that will not stop is, into its log.
    faulthandler.register(signal.SIGUSR1, all_threads=True)
    argv = list(sys.argv if args is None else args)
    program = argv[0].rsplit('/', 1)[-1] if argv else 'node'
    # rcl refuses a params file it cannot read with a traceback from inside rclpy.init: read
    # each first with the one reader of params files, which names the file and the problem.
    for entry in hosted:
        for path in params_files(argv if entry.node_args is None else entry.node_args):
            try:
                load_params_file(path)
            except ParamsFileError as error:
                print(f'{program}: invalid parameter: {error}', flush=True)
                raise SystemExit(2) from None
    rclpy.init(args=args, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    shutdown = _Shutdown()
    signal.signal(signal.SIGINT, shutdown.on_signal)
    signal.signal(signal.SIGTERM, shutdown.on_signal)
    nodes: list[tuple[Hosted, Node]] = []
    refused = False   # its parameters: then it leaves without a word
    waker: _Waker | None = None
    executor: Any = None
    config_errors = tuple(error for entry in hosted for error in entry.component.config_errors)
    current = hosted[0]
    try:
        try:
            for current in hosted:
                nodes.append((current, _make_node(current, argv)))
            names = [node.get_fully_qualified_name() for _, node in nodes]
            twice = sorted({name for name in names if names.count(name) > 1})
            if twice:
                # rcl only warns, and the two would answer each other's parameters and topics.
                raise ParameterError(f'two nodes named {twice[0]} in one process: give one '
                                     f'another name (--ros-args -r __node:=NAME --)')
            executor = make_executor()
            for _, node in nodes:
                executor.add_node(node)
            if hasattr(executor, 'wake'):
                wake = executor.wake   # the EventsExecutor takes no guard conditions
            else:
                wake = nodes[0][1].create_guard_condition(lambda: None).trigger
            waker = _Waker(wake, lifeline_fd())
            waker.start()
            profile_dir = os.environ.get(PROFILE_ENV)
            profiler = cProfile.Profile() if profile_dir else None
            if profiler is not None:
                profiler.enable()
            draining = [(h.component.drain, node) for h, node in nodes
                        if h.component.drain is not None]
            # A signal that comes before the wait leaves the guard triggered: the wait returns
            # at once, so none is missed between the check and the wait.
            try:
                while not shutdown.requested:
                    # With no timeout the EventsExecutor waits for a message only: its timers
                    # would never run, and a signal would wait for the next message.
                    executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
                if draining and not waker.orphaned:
                    _drain(executor, lambda: sum(count(node) for count, node in draining))
            finally:
                if profiler is not None and profile_dir:
                    profiler.disable()
                    name = '+'.join(node.get_name() for _, node in nodes)
                    profiler.dump_stats(os.path.join(profile_dir, f'{name}.prof'))
        except ExternalShutdownException:
            pass
        except (ParameterError, *config_errors) as error:  # type: ignore[misc]  # a starred tuple of classes
            # A bad parameter: say which value, exit non-zero before any message is sent.
            refused = True
            starting = len(nodes) < len(hosted)   # else a node refused one while running
            where = f'{program}: {current.label}' if current.label and starting else program
            print(f'{where}: invalid parameter: {error}', flush=True)
            raise SystemExit(2) from None
        finally:
            for entry, node in nodes:
                if not refused:
                    if entry.component.on_shutdown is not None:
                        entry.component.on_shutdown(node)
                    counter = getattr(node, 'publication_counter', None)
                    if counter is not None:
                        print(counter.report(), flush=True)
                node.destroy_node()
            # Before the fast exit: an executor left running keeps the context's DDS
            # participant alive, and os._exit then leaves its shared-memory segment and ports
            # in /dev/shm (about 0.5 MB, 4.4 MB with the images profile, per process and run).
            if executor is not None:
                executor.shutdown()
            if waker is not None:
                waker.close()
            rclpy.try_shutdown()
    except KeyboardInterrupt:
        _exit_now(130)
    _exit_now(0)


def _make_node(hosted: Hosted, argv: list[str]) -> Node:
    """The node of ``hosted``, its given parameters checked.

    Raises
    ------
    ParameterError
        A parameter of the wrong type, or one the node does not declare (named).
    """
    own_args = argv if hosted.node_args is None else hosted.node_args
    try:
        if hosted.node_args is None:
            node = hosted.component.factory()
        else:
            node = hosted.component.factory(cli_args=hosted.node_args,
                                            use_global_arguments=False)
    except (InvalidParameterTypeException, InvalidParameterValueException) as error:
        raise ParameterError(f'{error} (from {", ".join(params_files(own_args)) or "-p"})') \
            from None
    check_given_parameters(node, own_args)
    return node


# A drain must not hold up a graph that is stopping (a death stops it all within 2 s).
DRAIN_IDLE_S = 0.05
DRAIN_MAX_S = 0.5


def _drain(executor: Any, handled: Callable[[], int]) -> None:
    deadline = time.monotonic() + DRAIN_MAX_S
    while time.monotonic() < deadline:
        before = handled()
        executor.spin_once(timeout_sec=DRAIN_IDLE_S)
        if handled() == before:
            return


def _exit_now(code: int) -> None:
    """End the process as soon as the node is torn down.

    Everything that matters is done by now (last words sent, counts printed, node destroyed,
    context shut down); the interpreter's own teardown of numba, numpy and rclpy modules only
    adds a few hundred ms of CPU, which on a busy machine, with every node of a run exiting at
    once, made the graph outlive a killed orchestrator by more than a second.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
