"""Entry point of ./scripts/omni-micro: one sub-command per user task."""

from __future__ import annotations

import argparse
import signal
import sys

from omni_micro_cli.commands import (
    analyze,
    bench,
    bench_graph,
    bench_images,
    bench_study,
    compare_controllers,
    demo,
    figures,
    identify,
    record,
    recover,
    replay,
    run,
    simulate,
    soak,
    study,
    track,
    view,
)
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_sim.errors import CommandError, ParameterError, SimulationError

COMMANDS = (demo, run, view, record, replay, track, analyze, identify, recover, soak, simulate,
            figures, study, compare_controllers, bench, bench_graph, bench_images, bench_study)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog='omni-micro',
        description='Simulation of the tri-wheeled omnidirectional microrobot of Jin, Chen and '
                    'Li (ICIRA 2008): slip dynamics, overhead cameras, vision-feedback control. '
                    'Lengths are in mm and angles in degrees on the command line; every ROS '
                    'message is in SI units.')
    subparsers = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for command in COMMANDS:
        command.add_parser(subparsers)
    return parser


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    # SIGTERM (e.g. from `timeout` or CI) must unwind like Ctrl-C, so that a running graph is
    # shut down instead of orphaned.
    signal.signal(signal.SIGTERM, _interrupt)
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.handler(args))
    except (UsageError, ParameterError, CommandError) as error:
        print(f'omni-micro {args.command}: error: {error}', file=sys.stderr)
        return 2
    except (SimulationError, RunFailed) as error:
        print(f'omni-micro {args.command}: failed: {error}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f'omni-micro {args.command}: interrupted', file=sys.stderr)
        return 130
