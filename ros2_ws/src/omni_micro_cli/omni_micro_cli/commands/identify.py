"""`omni-micro identify BAG`: the robot's offsets (and friction, cantilever) from a recorded run.

From the bag alone: the commanded moves on /wheel_trajectory and the stationary captures on the
camera topics. The captures of each stop are averaged (their uncertainty from the camera's
/camera/<name>/pose_with_covariance, or, for a bag of bare PoseStamped captures, from the
scatter of each stop's frames); the stops and the moves between them are fitted by
:mod:`omni_micro_control.identification`. What the data do not pin down is reported as not
identifiable instead of as a number, and is left at its nominal value.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from omni_micro_cli.arguments import add_steering_argument
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.outputs import atomic_text, output_file
from omni_micro_common.conventions import CaptureUncertainty, quaternion_to_yaw, stamp_ns
from omni_micro_control.chains import Chain, RecordedMove, SteeringTracker, Stop
from omni_micro_control.errors import IdentificationError
from omni_micro_control.identification import (
    OFFSETS,
    PARAMETERS,
    STEERING_FITS,
    Fit,
    fit_parameters,
)
from omni_micro_control.observations import Observation, mean_observation
from omni_micro_sim.errors import CommandError
from omni_micro_sim.parameters import (
    MotorLimits,
    RobotParameters,
    SteeringParameters,
    steering_preset,
)
from omni_micro_sim.wheel_trajectory import TrajectoryPoint, command_from_points

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
                        help='print a final JSON line: wheel_offsets_deg, wheel_offsets_ci_deg '
                             '(95 %% half-widths), steering_backlash_deg and '
                             'steering_backlash_ci_deg when fitted, and every other fitted '
                             'parameter under its ROS parameter name')
    parser.add_argument('--write-params', type=output_file, metavar='FILE',
                        help='write a params YAML with the identified values for dynamics_node '
                             '(robot.*) and for the model controller (model.robot.*)')
    parser.set_defaults(handler=run)


@dataclass
class RecordedRun:
    chains: list[Chain]
    moves: int
    captures: int


def _stop(observations: list[Observation]) -> Stop:
    """One stop from its captures: their mean, with the camera's spread over sqrt(n), or, with
    no covariance recorded, the frames' own scatter."""
    mean = mean_observation(observations)
    if mean.uncertainty is None:
        if len(observations) < 3:
            raise UsageError(
                f'a stop at {mean.stamp_s:.3f} s has {len(observations)} bare capture(s) and no '
                f'covariance topic: at least 3 frames are needed to estimate their spread')
        xs = np.array([o.x_m for o in observations])
        ys = np.array([o.y_m for o in observations])
        phis = np.array([o.phi_rad - mean.phi_rad for o in observations])
        count = len(observations)
        mean_spread = CaptureUncertainty(
            max(float(np.std(xs, ddof=1)), 1e-12) / math.sqrt(count),
            max(float(np.std(ys, ddof=1)), 1e-12) / math.sqrt(count),
            max(float(np.std(np.remainder(phis + math.pi, 2 * math.pi) - math.pi, ddof=1)),
                1e-12) / math.sqrt(count))
    else:
        mean_spread = mean.uncertainty
    return Stop(mean.x_m, mean.y_m, mean.phi_rad, mean_spread, mean.stamp_s, mean.camera)


def read_run(bag: Path, steering: SteeringParameters | None = None) -> RecordedRun:
    """The chains of stops and moves a bag holds.

    A move's stop is every capture after its start and before the next move's start; a move
    with no capture after it (the run ended, or the robot left every field) ends a chain.
    With a steering motion (``steering``) each move first steers: its moves carry where the
    commands left the gear, and a move ends that much later.
    """
    tracker = None if steering is None or steering.instantaneous else SteeringTracker(steering)
    from omni_micro_tools.bag_reading import read_bag

    topics = ['/wheel_trajectory'] + [f'/camera/{c}/pose' for c in CAMERAS] + \
        [f'/camera/{c}/pose_with_covariance' for c in CAMERAS]
    data = read_bag(bag, topics)
    with_covariance = any(data.messages.get(f'/camera/{c}/pose_with_covariance')
                          for c in CAMERAS)
    observations: list[Observation] = []
    for camera in CAMERAS:
        if with_covariance:
            for msg in data.messages.get(f'/camera/{camera}/pose_with_covariance', []):
                try:
                    uncertainty = CaptureUncertainty.from_covariance(msg.pose.covariance)
                except ValueError as error:
                    raise UsageError(f'{str(bag)!r}: a {camera} capture at '
                                     f'{stamp_ns(msg.header.stamp)} ns: {error}') from None
                observations.append(_observation(msg.header, msg.pose.pose, camera,
                                                 uncertainty))
        else:
            observations += [_observation(msg.header, msg.pose, camera, None)
                             for msg in data.messages.get(f'/camera/{camera}/pose', [])]
    observations.sort(key=lambda o: o.stamp_s)
    # (start, end, move); a move cut short by a stop command is None: it breaks the chain.
    moves: list[tuple[float, float, RecordedMove | None]] = []
    for msg in data.messages.get('/wheel_trajectory', []):
        start_s = stamp_ns(msg.header.stamp) * 1e-9
        if not msg.points:
            if moves and start_s < moves[-1][1]:
                moves[-1] = (moves[-1][0], moves[-1][1], None)
            continue
        points = [TrajectoryPoint(p.time_from_start.sec + p.time_from_start.nanosec * 1e-9,
                                  list(p.positions), list(p.velocities)) for p in msg.points]
        try:
            command = command_from_points(msg.joint_names, points, start_s, start_s,
                                          MotorLimits(max_speed_rad_s=1e9))
        except CommandError as error:
            raise UsageError(f'{str(bag)!r}: the move at {start_s:.3f} s: {error}') from None
        assert command.profile is not None
        if tracker is None:
            commanded, steering_s = RecordedMove(command.steering_rad, command.profile), 0.0
        else:
            commanded = tracker.move(command.steering_rad, command.profile)
            steering_s = tracker.steering_time_s
        moves.append((start_s, start_s + steering_s + command.profile.end_time_s, commanded))
    # Too little in the bag to identify anything: the work fails (exit 1), as --help says; the
    # bag itself is a valid argument.
    if not moves:
        raise RunFailed(f'{str(bag)!r} has no move on /wheel_trajectory: nothing to identify')
    if not observations:
        raise RunFailed(f'{str(bag)!r} has no capture on the camera topics: nothing to '
                        f'identify')
    # Stop k holds the captures after move k-1's wheels stopped and before move k starts (the
    # camera may still count the robot as still in the first milliseconds of a move).
    windows = ([(-math.inf, moves[0][0])]
               + [(end, following[0]) for (_, end, _), following in itertools.pairwise(moves)]
               + [(moves[-1][1], math.inf)])
    groups: list[list[Observation]] = [[] for _ in windows]
    for observation in observations:
        for index, (after, before) in enumerate(windows):
            if after < observation.stamp_s < before:
                group = groups[index]
                if not group or group[0].camera == observation.camera:
                    group.append(observation)   # one camera per stop: the first to see it
                break
    chains: list[Chain] = []
    chain = Chain()
    for index, group in enumerate(groups):
        move = moves[index][2] if index < len(moves) else None
        if not group:
            chain = _close(chain, chains)
            continue
        chain.stops.append(_stop(group))
        if move is None:
            chain = _close(chain, chains)
        else:
            chain.moves.append(move)
    _close(chain, chains)
    return RecordedRun(chains, sum(len(c.moves) for c in chains), len(observations))


def _observation(header: Any, pose: Any, camera: str,
                 uncertainty: CaptureUncertainty | None) -> Observation:
    return Observation(stamp_ns(header.stamp) * 1e-9, pose.position.x, pose.position.y,
                       quaternion_to_yaw(pose.orientation.z, pose.orientation.w), camera,
                       uncertainty)


def _close(chain: Chain, chains: list[Chain]) -> Chain:
    """Keep ``chain``, without a last move no stop followed, if it links at least one move
    between two stops; return a new empty chain."""
    del chain.moves[max(0, len(chain.stops) - 1):]
    if chain.moves:
        chains.append(Chain(chain.stops, chain.moves))
    return Chain()


def identify(run: RecordedRun, names: Sequence[str],
             base: RobotParameters) -> tuple[Fit, dict[str, float]]:
    """Fit ``names``: the offsets first, then each other parameter added alone and kept only
    if the data pin it down (fitting all at once lets the poorly determined ones wander and
    drag the rest). Returns the fit of the identifiable ones and, for the others, the 95 %
    half-width they would have had.

    Raises
    ------
    IdentificationError
        If none of ``names`` is identifiable (the message says how far from it each was).
    """
    dropped: dict[str, float] = {}
    kept: list[str] = []
    fit: Fit | None = None
    ordered = [n for n in names if n in OFFSETS] + [n for n in names if n not in OFFSETS]
    first = [n for n in ordered if n in OFFSETS] or ordered[:1]
    for batch in [first] + [[n] for n in ordered if n not in first]:
        trial_names = kept + batch
        initial = None
        if fit is not None:
            initial = np.concatenate([fit.values, [PARAMETERS[n].get(base) for n in batch]])
        trial = fit_parameters(run.chains, base, trial_names, initial=initial)
        vague = trial.unidentifiable()
        if any(name in vague for name in kept):
            vague = batch   # the newcomer made the others vague: it is not pinned down either
        for name in batch:
            if name in vague:
                dropped[name] = float(trial.half_widths_95[trial.names.index(name)])
        if not set(batch) <= set(vague):
            kept += [name for name in batch if name not in vague]
            fit = trial if not vague else fit_parameters(run.chains, base, kept)
    if fit is None:
        raise IdentificationError(_vague_text(dropped))
    return fit, dropped


def _vague_text(dropped: dict[str, float]) -> str:
    parts = []
    for name, width in dropped.items():
        spec = PARAMETERS[name]
        parts.append(f'{spec.label} (its 95 % interval would be +-{width * spec.display_scale:.3g}'
                     f' {spec.unit})'.replace(' )', ')'))
    return ('not identifiable from this bag, too little motion to pin down: '
            + ', '.join(parts))


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
        fit, dropped = identify(recorded, args.fit, RobotParameters(steering=steering))
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
        print(json.dumps(summary_json(fit, dropped)))
    if missing_offsets:
        raise RunFailed(_vague_text({name: dropped[name] for name in missing_offsets}))
    return 0
