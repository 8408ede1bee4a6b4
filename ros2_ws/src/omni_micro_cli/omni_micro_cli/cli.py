"""The ``omni-micro`` console script: one sub-command per user task.

The framework is kept apart from the commands, as pip's is: :data:`COMMANDS` maps each name to
the module that implements it, and a module is imported only when its command runs (or its
``--help`` is asked for). ``omni-micro --help`` therefore loads none of numba, scipy,
matplotlib, pyarrow, dask, cv2, rosbags or rclpy.

Every command ends the same way: exit 0 on success, 2 with one line naming a value it cannot
use, 1 with one line saying why the work failed, 130 when interrupted. An exception nobody
foresaw is one line too, with the file its traceback was written to (``--debug`` or
``OMNI_MICRO_DEBUG=1`` print it instead).
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import difflib
import importlib
import os
import re
import signal
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from omni_micro_cli.outputs import json_alone_on_stdout
from omni_micro_common.errors import OmniMicroError

DEBUG_ENV = 'OMNI_MICRO_DEBUG'


@dataclass(frozen=True)
class Command:
    module: str                     # defines add_parser(subparsers), which sets a handler
    summary: str                    # the line in `omni-micro --help`
    aliases: tuple[str, ...] = ()


COMMANDS: dict[str, Command] = {
    'demo': Command('demo', "the paper's results reproduced: Fig. 11 through the node graph"),
    'run': Command('run', 'drive the robot to a goal through the ROS 2 node graph'),
    'graph': Command('graph', 'the node graph as a picture (SVG/PNG) or JSON, read from a '
                              'running graph'),
    'view': Command('view', 'serve a running graph to Foxglove (run --view starts this)'),
    'record': Command('record', "record the graph's topics into a rosbag2 bag until Ctrl-C"),
    'replay': Command('replay', "publish a bag's messages again, e.g. to feed a node"),
    'track': Command('track', "run the tracker on a bag's recorded images (a real camera's, "
                              'say)'),
    'preflight': Command('preflight', "check the bench's live camera and robot drivers before "
                                      'a run: one line per thing to fix'),
    'record-target': Command('record_target', "a simulated camera's frames of a calibration "
                                              'target, to rehearse calibrate-camera'),
    'calibrate-camera': Command('calibrate_camera', "a camera's map to the platform from its "
                                                    'frames of a target (for tracker_node)'),
    'analyze': Command('analyze', 'figures and a summary of a recorded bag', ('analyse',)),
    'identify': Command('identify', "the robot's wheel offsets (and friction) from a recorded "
                                    'run'),
    'bag-recover': Command('recover', 'make a readable bag from one whose recorder was killed'),
    'soak': Command('soak', 'many goals in one graph run: memory growth and bag completeness'),
    'fleet': Command('fleet', 'several robots on one platform (a fleet): a plan '
                              'that keeps them apart, driven in one process'),
    'fleet-study': Command('fleet_study', 'the fleet measured: throughput against the '
                                          'number of robots, crossing runs'),
    'simulate': Command('simulate', 'one open-loop move from rest at the origin (no ROS)'),
    'figures': Command('figures', "reproduce the paper's open-loop figures and compare its "
                                  'numbers'),
    'study': Command('study.command', 'sweeps and Monte Carlo of the loop or of open-loop '
                                      'moves, on Dask'),
    'compare-controllers': Command('compare_controllers',
                                   "the paper's rule against the model-based controller"),
    'bench': Command('bench', 'benchmark the slip core (ratios against a reference in the '
                              'same run)'),
    'bench-graph': Command('bench_graph', 'real-time factor the node graph reaches on Fig. 11, '
                                          'idle and busy'),
    'bench-fleet': Command('bench_fleet', 'robot-seconds per wall second the node graph runs '
                                          'against the fleet\'s size, separate and composed'),
    'bench-images': Command('bench_images', 'cost of the rendered cameras and the tracker, per '
                                            'frame and in the loop'),
    'bench-startup': Command('bench_startup', 'start-up time of the command line against the '
                                              'bare interpreter'),
    'bench-study': Command('bench_study', 'benchmark studies: plain loop vs 1 and 2 Dask '
                                          'workers, 1000 runs'),
}
ALIASES = {alias: name for name, command in COMMANDS.items() for alias in command.aliases}


class _Parser(argparse.ArgumentParser):
    """argparse with a bad argument said in one line (the usage is --help's, not printed before
    every mistake) and no abbreviations (``run --goal`` would be taken for ``--goal-mm``, and a
    typo of a future flag for another flag)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault('allow_abbrev', False)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        unknown = re.search(r"argument COMMAND: invalid choice: '([^']*)'", message)
        if unknown:
            close = difflib.get_close_matches(unknown.group(1), [*COMMANDS, *ALIASES], n=1)
            message = (f'{unknown.group(1)!r} is not a command'
                       + (f'; did you mean {close[0]}?' if close else '')
                       + f' ({self.prog} --help lists them)')
        else:
            message += f' ({self.prog} --help lists the arguments)'
        self.exit(2, f'{self.prog}: error: {message}\n')


class _CommandSubparsers:
    """What a command module's ``add_parser`` is given: argparse's sub-parser action, with the
    command's summary and aliases taken from :data:`COMMANDS` (one place for each)."""

    def __init__(self, action: argparse._SubParsersAction) -> None:
        self._action = action

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser:
        command = COMMANDS[name]
        return self._action.add_parser(name, help=command.summary,
                                       aliases=list(command.aliases), **kwargs)


def refuse_unknown(parser: argparse.ArgumentParser, command: str, unknown: list[str]) -> NoReturn:
    """Arguments ``command`` does not take, said by its own parser (its --help lists them),
    with the closest spelling it takes."""
    commands = next(action for action in parser._actions
                    if isinstance(action, argparse._SubParsersAction))
    own: argparse.ArgumentParser = commands.choices[command]
    # Compared without the dashes every flag shares (--bogus is not close to --robots).
    names = [flag[2:] for flag in own._option_string_actions if flag.startswith('--')]
    close = [match for word in unknown if word.startswith('-')
             for match in difflib.get_close_matches(word.split('=')[0].lstrip('-'), names, n=1)]
    own.error(f'unrecognized arguments: {" ".join(unknown)}'
              + (f'; did you mean --{close[0]}?' if close else ''))


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The parser, with every command's own arguments, or only ``only``'s (the others are
    listed with their summary, their modules not imported; ``''``: none imported)."""
    parser = _Parser(
        prog='omni-micro',
        description='Simulation of the tri-wheeled omnidirectional microrobot of Jin, Chen and '
                    'Li (ICIRA 2008): slip dynamics, overhead cameras, vision-feedback control. '
                    'Lengths are in mm and angles in degrees on the command line; every ROS '
                    'message is in SI units.',
        epilog='Exit codes: 0 done, 1 the work failed (one line says why), 2 a value it cannot '
               'use (one line names it), 130 interrupted.')
    parser.add_argument('--debug', action='store_true',
                        help=f'print the traceback of an unexpected error (or set {DEBUG_ENV}=1)')
    subparsers = parser.add_subparsers(dest='command', metavar='COMMAND', required=True,
                                       parser_class=_Parser)
    registrar = _CommandSubparsers(subparsers)
    for name, command in COMMANDS.items():
        if only is None or name == only:
            module = importlib.import_module(f'omni_micro_cli.commands.{command.module}')
            module.add_parser(registrar)
        else:
            subparsers.add_parser(name, help=command.summary, aliases=list(command.aliases),
                                  add_help=False)
    return parser


def command_named(argv: list[str]) -> str | None:
    """The command the arguments ask for (aliases resolved), or None (none, or unknown)."""
    for word in argv:
        if word == '--':
            return None
        if not word.startswith('-'):
            name = ALIASES.get(word, word)
            return name if name in COMMANDS else None
    return None


class _Interrupt:
    """SIGTERM unwinds like Ctrl-C, once: ``timeout`` signals a process and its group, and the
    second of the pair raised another KeyboardInterrupt inside the first's clean-up (a traceback
    while a study parsed its file; its "K of N runs kept" line lost). A flag, not SIG_IGN,
    which the processes started during the clean-up would inherit."""

    def __init__(self) -> None:
        self.raised = False

    def __call__(self, signum: int, frame: object) -> None:
        if not self.raised:
            self.raised = True
            raise KeyboardInterrupt


def _report_unexpected(command: str, error: BaseException) -> str:
    """Write the traceback to a file and return where, for the one-line message."""
    folder = Path(tempfile.gettempdir()) / f'omni-micro-{os.getuid()}'
    folder.mkdir(exist_ok=True)
    path = folder / f'{command}-{time.strftime("%Y%m%d-%H%M%S")}-{os.getpid()}.log'
    path.write_text(''.join(traceback.format_exception(error)))
    return str(path)


def main(argv: list[str] | None = None) -> int:
    # SIGTERM (e.g. from `timeout` or CI) must unwind like Ctrl-C, so that a running graph is
    # shut down instead of orphaned.
    signal.signal(signal.SIGTERM, _Interrupt())
    # DDS stays on loopback however the command is started (the installed script needs no
    # wrapper): the orchestrator's own node must discover as its children do.
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.pop('ROS_LOCALHOST_ONLY', None)
    # Before any command imports numpy (omni_micro_bringup.processes says why).
    from omni_micro_bringup.processes import SINGLE_THREADED_BLAS
    for name, value in SINGLE_THREADED_BLAS.items():
        os.environ.setdefault(name, value)
    arguments = sys.argv[1:] if argv is None else argv
    # No command named (--help, or a typo): list the commands, import none of them.
    try:
        parser = build_parser(command_named(arguments) or '')
        args, unknown = parser.parse_known_args(arguments)
        if unknown:
            refuse_unknown(parser, args.command, unknown)
    except (OmniMicroError, OSError) as error:
        # A check inside an argument's type (a path the system refuses, say): still one line.
        print(f'omni-micro: error: {error}', file=sys.stderr)
        return 2
    except KeyboardInterrupt:   # while the command's modules load
        print('omni-micro: interrupted', file=sys.stderr)
        return 130
    debug = args.debug or os.environ.get(DEBUG_ENV, '') not in ('', '0')
    try:
        if getattr(args, 'json', False):
            with json_alone_on_stdout():
                return int(args.handler(args))
        return int(args.handler(args))
    except KeyboardInterrupt:
        print(f'omni-micro {args.command}: interrupted', file=sys.stderr)
        return 130
    except OmniMicroError as error:
        if debug:
            traceback.print_exc()
        # A value the command cannot use is a ValueError; anything else is a failure.
        if isinstance(error, ValueError):
            print(f'omni-micro {args.command}: error: {error}', file=sys.stderr)
            return 2
        print(f'omni-micro {args.command}: failed: {error}', file=sys.stderr)
        return 1
    except Exception as error:
        if debug:
            raise
        where = _report_unexpected(args.command, error)
        print(f'omni-micro {args.command}: failed unexpectedly: {type(error).__name__}: '
              f'{error} (traceback in {where}; --debug prints it)', file=sys.stderr)
        return 1


def command() -> NoReturn:
    """The installed ``omni-micro``: :func:`main`, then an exit without the interpreter's
    teardown (:func:`_end_now`)."""
    returned: list[int] = []
    # Registered before main() runs: exit hooks run last registered first, so this one runs
    # after every hook the command's modules register (the warm-start zygote's closing).
    atexit.register(_end_now, returned)
    returned.append(main())
    sys.exit(returned[0])


def _end_now(returned: list[int]) -> None:
    """Once main() has returned and every other exit hook has run, end the process at once.

    What is left then is the interpreter's teardown of the modules the command loaded: after a
    DDS participant (the orchestration's, the preflight's) it took 0.15 s of wall time (0.37 s
    against 0.21 s for a bare rclpy node, measured), every command, after its result was
    printed. The participant itself is gone by then (rclpy shut down: no shared-memory file
    left), and threads that are not daemons were joined before the exit hooks ran. A command
    that did not return (``--help``, an exit from inside) ends as Python ends it."""
    if not returned:
        return
    if 'logging' in sys.modules:   # its own exit hook may come after this one
        sys.modules['logging'].shutdown()
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):   # a closed pipe: nothing more can be said
            stream.flush()
    os._exit(returned[0])
