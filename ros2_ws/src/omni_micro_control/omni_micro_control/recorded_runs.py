"""A recorded run as identification reads it: the commanded moves on /wheel_trajectory and the
stationary captures on the camera topics, made into chains of stops linked by moves
(:mod:`omni_micro_control.chains`).

The messages may come from a bag (``omni-micro identify`` reads one with rosbags) or from live
subscriptions: only their fields are read. A stop's captures are averaged, their uncertainty
from the camera's covariance or, for bare PoseStamped captures, from the scatter of the stop's
frames.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from omni_micro_common.conventions import CaptureUncertainty, quaternion_to_yaw, stamp_ns
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_TOPICS,
    WHEEL_TRAJECTORY_TOPIC,
)
from omni_micro_control.chains import Chain, RecordedMove, SteeringTracker, Stop
from omni_micro_control.errors import IdentificationError, RecordingError
from omni_micro_control.observations import Observation, mean_observation
from omni_micro_sim.errors import CommandError
from omni_micro_sim.parameters import MotorLimits, SteeringParameters
from omni_micro_sim.wheel_trajectory import TrajectoryPoint, command_from_points

CAMERAS = tuple(CAPTURE_TOPICS)
# What read_run reads: the moves, and the captures with their covariance or bare.
RUN_TOPICS = (WHEEL_TRAJECTORY_TOPIC, *CAPTURE_TOPICS.values(),
              *CAPTURE_COVARIANCE_TOPICS.values())


class TooLittleRecordedError(IdentificationError):
    """The recording is sound but holds too little: no move, or no capture."""


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
            raise RecordingError(
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


def read_run(messages: Mapping[str, Sequence[Any]], source: str,
             steering: SteeringParameters | None = None) -> RecordedRun:
    """The chains of stops and moves a recorded run holds: ``messages`` by topic (of
    :data:`RUN_TOPICS`, decoded by rclpy or rosbags alike), ``source`` what to call the
    recording in a message (a bag's path).

    A move's stop is every capture after its start and before the next move's start; a move
    with no capture after it (the run ended, or the robot left every field) ends a chain.
    With a steering motion (``steering``) each move first steers: its moves carry where the
    commands left the gear, and a move ends that much later.
    """
    tracker = None if steering is None or steering.instantaneous else SteeringTracker(steering)
    with_covariance = any(messages.get(CAPTURE_COVARIANCE_TOPICS[c]) for c in CAMERAS)
    observations: list[Observation] = []
    for camera in CAMERAS:
        if with_covariance:
            for msg in messages.get(CAPTURE_COVARIANCE_TOPICS[camera], []):
                try:
                    uncertainty = CaptureUncertainty.from_covariance(msg.pose.covariance)
                except ValueError as error:
                    raise RecordingError(f'{source!r}: a {camera} capture at '
                                     f'{stamp_ns(msg.header.stamp)} ns: {error}') from None
                observations.append(_observation(msg.header, msg.pose.pose, camera,
                                                 uncertainty))
        else:
            observations += [_observation(msg.header, msg.pose, camera, None)
                             for msg in messages.get(CAPTURE_TOPICS[camera], [])]
    observations.sort(key=lambda o: o.stamp_s)
    # (start, end, move); a move cut short by a stop command is None: it breaks the chain.
    moves: list[tuple[float, float, RecordedMove | None]] = []
    for msg in messages.get(WHEEL_TRAJECTORY_TOPIC, []):
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
            raise RecordingError(f'{source!r}: the move at {start_s:.3f} s: {error}') from None
        assert command.profile is not None
        if tracker is None:
            commanded, steering_s = RecordedMove(command.steering_rad, command.profile), 0.0
        else:
            commanded = tracker.move(command.steering_rad, command.profile)
            steering_s = tracker.steering_time_s
        moves.append((start_s, start_s + steering_s + command.profile.end_time_s, commanded))
    # Too little recorded to identify anything: not a malformed one.
    if not moves:
        raise TooLittleRecordedError(f'{source!r} has no move on /wheel_trajectory: nothing to '
                                     'identify')
    if not observations:
        raise TooLittleRecordedError(f'{source!r} has no capture on the camera topics: nothing to '
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
