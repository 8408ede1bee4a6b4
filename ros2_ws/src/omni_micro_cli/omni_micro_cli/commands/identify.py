"""`omni-micro identify BAG`: the robot's offsets (and friction, cantilever) from a recorded run.

From the bag alone: the commanded moves on /wheel_trajectory and the stationary captures on the
camera topics, made into chains of stops and moves by :mod:`omni_micro_control.recorded_runs` (the
captures of each stop averaged, their uncertainty from the camera's
/camera/<name>/pose_with_covariance, or, for a bag of bare PoseStamped captures, from the scatter
of each stop's frames) and fitted by :mod:`omni_micro_control.identification`. What the data do not
pin down is reported as not identifiable instead of as a number, and is left at its nominal value.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from omni_micro_cli.arguments import add_steering_argument
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.outputs import atomic_text, output_file, print_json
from omni_micro_control import recorded_runs
from omni_micro_control.errors import IdentificationError, RecordingError
from omni_micro_control.identification import (
    OFFSETS,
    PARAMETERS,
    STEERING_FITS,
    identify,
    vague_text,
)
from omni_micro_control.identification_report import params_yaml, report, summary_json
from omni_micro_control.recorded_runs import RUN_TOPICS, RecordedRun, TooLittleRecordedError
from omni_micro_sim.parameters import (
    RobotParameters,
    SteeringParameters,
    steering_preset,
)

CAMERAS = ('macro', 'micro')
DEFAULT_FIT = ('xi2', 'xi3', 'mu_longitudinal', 'mu_transverse', 'cantilever_offset_m')


def parameter_names(text: str) -> tuple[str, ...]:
    names = tuple(name.strip() for name in text.split(',') if name.strip())
    unknown = [name for name in names if name not in PARAMETERS]
    if unknown or not names:
        raise argparse.ArgumentTypeError(
            f'{text!r}: expected a comma-separated list of {", ".join(PARAMETERS)}')
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise argparse.ArgumentTypeError(f'{text!r}: {", ".join(repeated)} named twice (each '
                                         'parameter is fitted once)')
    return names


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'identify',
        description="Least-squares fit of the robot's unknown parameters to a recorded run: "
                    'the moves on /wheel_trajectory and the stationary captures on the '
                    'camera topics, nothing else. Prints each parameter with its 95 % '
                    'interval, or says it is not identifiable from this bag, and the '
                    "residual of every stop. Exit 0 when xi2 and xi3 were identified, 1 when "
                    'the bag holds too little motion, 2 for a bad argument.')
    parser.add_argument('bag', type=Path, metavar='BAG', help='a bag recorded with --record')
    parser.add_argument('--fit', type=parameter_names, metavar='NAMES',
                        help=f'parameters to fit, comma-separated (default {",".join(DEFAULT_FIT)}'
                             '); those the data do not pin down stay nominal')
    add_steering_argument(parser, scope='. The steering of the robot that made the bag: with '
                          'realistic, each move steers from where the commands left the gear, '
                          'and backlash and contact_radius (the pivot friction) can be fitted '
                          '(default fit: the above and backlash)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the report on '
                             'stderr): wheel_offsets_deg, wheel_offsets_ci_deg '
                             '(95 %% half-widths), steering_backlash_deg and '
                             'steering_backlash_ci_deg when fitted, and every other fitted '
                             'parameter under its ROS parameter name')
    parser.add_argument('--write-params', type=output_file, metavar='FILE',
                        help='write a params YAML with the identified values for dynamics_node '
                             '(robot.*) and for the model controller (model.robot.*)')
    parser.set_defaults(handler=run)


def read_run(bag: Path, steering: SteeringParameters | None = None) -> RecordedRun:
    """The chains of stops and moves ``bag`` holds (:func:`.recorded_runs.read_run`)."""
    from omni_micro_tools.bag_reading import read_bag

    data = read_bag(bag, list(RUN_TOPICS))
    try:
        return recorded_runs.read_run(data.messages, str(bag), steering)
    except RecordingError as error:
        raise UsageError(str(error)) from None
    except TooLittleRecordedError as error:
        # The bag is a valid argument: the work fails (exit 1), as --help says.
        raise RunFailed(str(error)) from None


def run(args: argparse.Namespace) -> int:
    steering = steering_preset(args.steering)
    names = args.fit or (DEFAULT_FIT + (('backlash',) if args.steering != 'ideal' else ()))
    needs_motion = [name for name in names if name in STEERING_FITS]
    if needs_motion and steering.instantaneous:
        raise UsageError(f'--fit {",".join(needs_motion)}: ideal steering has no backlash or '
                         'pivot friction to fit; give --steering realistic (the steering of '
                         'the robot that made the bag)')
    args.fit = names
    recorded = read_run(args.bag, steering)
    if not recorded.chains:
        raise RunFailed(f'{str(args.bag)!r}: no move between two seen stops: nothing to '
                        f'identify (not identifiable)')
    print(f'identify: fitting {", ".join(args.fit)} to {recorded.moves} moves', file=sys.stderr)
    try:
        fit, dropped = identify(recorded.chains, args.fit, RobotParameters(steering=steering))
    except IdentificationError as error:
        raise RunFailed(str(error)) from None
    print(report(fit, dropped, recorded))
    missing_offsets = [name for name in OFFSETS if name in dropped]
    if args.write_params is not None:
        if missing_offsets:
            print(f'identify: {args.write_params} not written: the offsets are not identified',
                  file=sys.stderr)
        else:
            atomic_text(args.write_params, params_yaml(fit))
            print(f'identify: params written to {args.write_params}', file=sys.stderr)
    if args.json:
        print_json(summary_json(fit, dropped))
    if missing_offsets:
        raise RunFailed(vague_text({name: dropped[name] for name in missing_offsets}))
    return 0
