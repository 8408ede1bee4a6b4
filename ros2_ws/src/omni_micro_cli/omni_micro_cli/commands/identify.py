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
import math
import sys
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from omni_micro_cli.arguments import add_steering_argument
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.outputs import atomic_text, output_file, print_json
from omni_micro_control import recorded_runs
from omni_micro_control.errors import IdentificationError, RecordingError
from omni_micro_control.identification import (
    OFFSETS,
    PARAMETERS,
    STEERING_FITS,
    Fit,
    identify,
    vague_text,
)
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


def report(fit: Fit, dropped: dict[str, float], run: RecordedRun) -> str:
    lines = ['| parameter | ROS parameter | estimate | 95 % interval |', '|---|---|---|---|']
    for index, name in enumerate(fit.names):
        spec = PARAMETERS[name]
        value = fit.values[index] * spec.display_scale
        width = fit.half_widths_95[index] * spec.display_scale
        lines.append(f'| {spec.label} | `{spec.ros_name}` | {value:.4f} {spec.unit} | '
                     f'+-{width:.4f} {spec.unit} |')
    for name, width in dropped.items():
        spec = PARAMETERS[name]
        lines.append(f'| {spec.label} | `{spec.ros_name}` | not identifiable (left nominal) | '
                     f'would be +-{width * spec.display_scale:.3g} {spec.unit} |')
    lines += ['', f'{run.moves} moves between {sum(len(c.stops) for c in run.chains)} stops '
                  f'({run.captures} captures, {len(run.chains)} chain(s)); reduced chi-square '
                  f'{fit.reduced_chi_square:.2f} over {fit.degrees_of_freedom} degrees of '
                  f'freedom (about 1 when the model explains the stops to the cameras\' noise)',
              '', '| stop | camera | residual x (um) | residual y (um) | heading (mrad) |'
                  ' normalised |', '|---|---|---|---|---|---|']
    number = 0
    for chain, residuals, normalised in zip(run.chains, fit.residuals,
                                            fit.normalised_residuals, strict=True):
        for stop, residual, scaled in zip(chain.stops, residuals, normalised, strict=True):
            number += 1
            lines.append(f'| {number} | {stop.camera} | {residual[0] * 1e6:+.3f} | '
                         f'{residual[1] * 1e6:+.3f} | {residual[2] * 1e3:+.4f} | '
                         f'{float(np.max(np.abs(scaled))):.2f} |')
    return '\n'.join(lines)


def summary_json(fit: Fit, dropped: dict[str, float]) -> dict[str, object]:
    offsets = [0.0, None, None]
    widths = [0.0, None, None]
    result: dict[str, object] = {}
    for index, name in enumerate(fit.names):
        if name in OFFSETS:
            slot = OFFSETS.index(name) + 1
            offsets[slot] = math.degrees(float(fit.values[index]))
            widths[slot] = math.degrees(float(fit.half_widths_95[index]))
        else:
            if name == 'backlash':
                result['steering_backlash_deg'] = math.degrees(float(fit.values[index]))
                result['steering_backlash_ci_deg'] = math.degrees(
                    float(fit.half_widths_95[index]))
            result[PARAMETERS[name].ros_name] = float(fit.values[index])
            result[f'{PARAMETERS[name].ros_name}_ci'] = float(fit.half_widths_95[index])
    result = {'wheel_offsets_deg': offsets, 'wheel_offsets_ci_deg': widths, **result,
              'not_identifiable': sorted(PARAMETERS[name].ros_name for name in dropped),
              'reduced_chi_square': fit.reduced_chi_square,
              'degrees_of_freedom': fit.degrees_of_freedom}
    return result


def params_yaml(fit: Fit) -> str:
    robot: dict[str, Any] = {}
    for index, name in enumerate(fit.names):
        if name not in OFFSETS:
            # Nested as the ROS parameter name says (robot.steering.backlash_rad).
            *groups, leaf = PARAMETERS[name].ros_name.removeprefix('robot.').split('.')
            section = robot
            for group in groups:
                section = section.setdefault(group, {})
            section[leaf] = float(fit.values[index])
    robot['wheel_offsets_rad'] = [float(v) for v in fit.robot.wheel_offsets_rad]
    header = ('# Identified by omni-micro identify: the dynamics simulate this robot, and the\n'
              '# model controller starts from it. Use with: omni-micro run --params FILE\n')
    return header + yaml.safe_dump({
        'dynamics_node': {'ros__parameters': {'robot': robot}},
        'controller_node': {'ros__parameters': {'model': {'robot': robot}}},
    }, sort_keys=False)


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
