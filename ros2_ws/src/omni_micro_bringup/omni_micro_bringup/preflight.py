"""What a lab checks before a bench run, from what the live drivers send: each camera's frames
(encoding, size, the rate sent by their stamps and the rate arriving, frames lost, their stamps
against this machine's clock, the CameraInfo beside them, the QoS offered), each robot's joint
states (arriving, their rate, their joints, the QoS offered), and each robot of several named
by its code as the tracker names them. Plain Python: the listening is
:mod:`omni_micro_bringup.preflight_probe`'s.

Each finding that needs action is one line naming the value and what to do.
"""

from __future__ import annotations

import statistics
from collections import Counter
from dataclasses import dataclass, field

from omni_micro_common.clocks import CLOCK_MISMATCH_S
from omni_micro_common.conventions import JOINT_NAMES
from omni_micro_common.installed import dds_profile_to_export
from omni_micro_vision.encodings import ENCODINGS
from omni_micro_vision.frame_losses import FrameLosses, likely_cause

# Frames older than this on arrival hold a servo's correction back (docs/images.md, bench).
LATE_FRAME_S = 0.1
# Stamps this far ahead of this machine's clock: the driver's clock is off.
AHEAD_S = 0.005


@dataclass
class Offered:
    """A publisher's QoS, as discovery says it (a history's depth is not sent on the wire)."""

    node: str
    reliability: str
    durability: str

    def __str__(self) -> str:
        return f'{self.node}: {self.reliability}, {self.durability}'


@dataclass
class CameraWatch:
    """One camera's frames and CameraInfo as they came."""

    name: str
    image_topic: str
    info_topic: str
    expected_size: tuple[int, int] | None = None     # the tracker's params (columns, rows)
    frames: int = 0
    encodings: Counter[str] = field(default_factory=Counter)
    sizes: Counter[tuple[int, int]] = field(default_factory=Counter)
    frame_bytes: int = 0
    ages_s: list[float] = field(default_factory=list)
    infos: int = 0
    info_stamps_ns: tuple[int, int] | None = None     # the first and last CameraInfo's
    info_size: tuple[int, int] | None = None
    info_k_zero: bool = False
    offered: list[Offered] = field(default_factory=list)
    losses: FrameLosses = field(init=False)
    # Robots named in the last frame, and why the others were not (with --robots).
    named: dict[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.losses = FrameLosses(self.name, self.image_topic)

    def on_frame(self, stamp_ns: int, arrived_ns: int, encoding: str, width: int, height: int,
                 size_bytes: int) -> None:
        self.frames += 1
        self.encodings[encoding] += 1
        self.sizes[width, height] += 1
        self.frame_bytes = size_bytes
        self.ages_s.append((arrived_ns - stamp_ns) * 1e-9)
        self.losses.add(stamp_ns, lambda: '')

    def on_info(self, stamp_ns: int, width: int, height: int, k: list[float]) -> None:
        self.infos += 1
        first = self.info_stamps_ns[0] if self.info_stamps_ns else stamp_ns
        self.info_stamps_ns = (first, stamp_ns)
        self.info_size = (width, height)
        self.info_k_zero = not any(k)
        self.losses.add_info(stamp_ns)

    @property
    def sent_hz(self) -> float | None:
        period = self.losses.period_ns
        return 1e9 / period if period else None

    def arriving_hz(self, seconds: float) -> float:
        return self.frames / seconds

    @property
    def age_s(self) -> float | None:
        return statistics.median(self.ages_s) if self.ages_s else None

    def findings(self, seconds: float, best_effort_reader: bool = True) -> list[str]:
        where = f'{self.name} ({self.image_topic})'
        if not self.offered:
            return [f'{where}: nothing publishes it: start the camera driver in this domain, '
                    f'or name its topic (--camera {self.name}=TOPIC)']
        if not self.frames:
            return [f'{where}: published ({"; ".join(map(str, self.offered))}) but no frame '
                    f'came in {seconds:g} s: is the driver streaming?']
        said = []
        unread = sorted(set(self.encodings) - set(ENCODINGS))
        if unread:
            said.append(f'{where}: encoding {", ".join(unread)} is not one the tracker reads '
                        f'({", ".join(sorted(ENCODINGS))}): set the driver\'s output encoding')
        size = self.sizes.most_common(1)[0][0]
        if self.expected_size is not None and size != self.expected_size:
            said.append(f'{where}: frames are {size[0]} x {size[1]}, the tracker\'s params say '
                        f'{self.expected_size[0]} x {self.expected_size[1]}: set '
                        f'{self.name}.resolution_px, or calibrate this camera')
        if self.losses.lost_total:
            # It does not track: only the transport's causes can be its (no queue depth).
            cause = likely_cause(self.frame_bytes, best_effort_reader, 0.0,
                                 (self.losses.period_ns or 0.0) * 1e-9,
                                 dds_profile_to_export(), 0)
            said.append(f'{where}: {self.losses.lost_total} of {self.losses.sent_total} frames '
                        f'lost on the way ({self.sent_hz or 0.0:.1f} Hz sent by their stamps, '
                        f'{self.arriving_hz(seconds):.1f} Hz arriving); {cause}')
        age = self.age_s
        if age is not None:
            if abs(age) > CLOCK_MISMATCH_S:
                said.append(f'{where}: frames are stamped {age:+.1f} s from this machine\'s '
                            'clock: the driver must stamp with the system clock (not sim '
                            'time, not its device\'s own counter)')
            elif age > LATE_FRAME_S:
                said.append(f'{where}: frames arrive {age * 1e3:.0f} ms after their stamps '
                            f'(more than {LATE_FRAME_S * 1e3:.0f} ms): the servo waits that '
                            'long for each capture; check the driver\'s queue and transport')
            elif age < -AHEAD_S:
                said.append(f'{where}: frames are stamped {-age * 1e3:.0f} ms ahead of this '
                            'machine\'s clock: the driver\'s clock is off (chrony or ptp)')
        info = f'{self.name} ({self.info_topic})'
        if not self.infos:
            said.append(f'{info}: no CameraInfo came in {seconds:g} s: the tracker cannot '
                        'check the frames\' size and lens; have the driver publish it')
        else:
            if self.info_k_zero:
                said.append(f'{info}: K is all zero (no intrinsic calibration): calibrate the '
                            'lens with the ROS camera_calibration package')
            if self.info_size != size:
                assert self.info_size is not None
                said.append(f'{info}: says {self.info_size[0]} x {self.info_size[1]}, the '
                            f'frames are {size[0]} x {size[1]}: the driver\'s calibration file '
                            'is of another mode')
        return said

    def summary(self, seconds: float) -> dict[str, object]:
        size = self.sizes.most_common(1)[0][0] if self.sizes else None
        return {'camera': self.name, 'image_topic': self.image_topic,
                'info_topic': self.info_topic, 'frames': self.frames,
                'encoding': self.encodings.most_common(1)[0][0] if self.encodings else None,
                'size': list(size) if size else None, 'frame_bytes': self.frame_bytes,
                'sent_hz': _rounded(self.sent_hz), 'arriving_hz': _rounded(
                    self.arriving_hz(seconds)),
                'frames_lost': self.losses.lost_total, 'frames_sent': self.losses.sent_total,
                'age_s': _rounded(self.age_s, 4), 'camera_info': self.infos,
                'camera_info_stamps_s': [stamp * 1e-9 for stamp in self.info_stamps_ns]
                if self.info_stamps_ns else None,
                'calibrated': None if not self.infos else not self.info_k_zero,
                'qos_offered': [str(o) for o in self.offered], 'named': self.named}


@dataclass
class RobotWatch:
    """One robot's joint states as they came."""

    name: str
    topic: str
    states: int = 0
    stamps_ns: list[int] = field(default_factory=list)
    joints: set[str] = field(default_factory=set)
    offered: list[Offered] = field(default_factory=list)

    def on_state(self, stamp_ns: int, names: list[str]) -> None:
        self.states += 1
        self.stamps_ns.append(stamp_ns)
        self.joints.update(names)

    @property
    def rate_hz(self) -> float | None:
        if len(self.stamps_ns) < 2 or self.stamps_ns[-1] <= self.stamps_ns[0]:
            return None
        return (len(self.stamps_ns) - 1) / ((self.stamps_ns[-1] - self.stamps_ns[0]) * 1e-9)

    def findings(self, seconds: float) -> list[str]:
        where = f'{self.name} ({self.topic})'
        if not self.offered:
            return [f'{where}: nothing publishes it: start the robot\'s driver in this domain']
        said = [f'{where}: {o} offers best effort; controller_node reads it reliable and they '
                'never match: make the driver publish reliable (joint_state_broadcaster does)'
                for o in self.offered if o.reliability == 'best_effort']
        if not self.states:
            return [*said, f'{where}: published but no joint state came in {seconds:g} s: '
                           'is the driver\'s hardware up?']
        missing = [name for name in JOINT_NAMES if name not in self.joints]
        if missing:
            said.append(f'{where}: no {", ".join(missing)} among its joints '
                        f'({", ".join(sorted(self.joints))}): controller_node reads '
                        f'{", ".join(JOINT_NAMES)}')
        return said

    def summary(self) -> dict[str, object]:
        return {'robot': self.name, 'topic': self.topic, 'states': self.states,
                'rate_hz': _rounded(self.rate_hz), 'joints': sorted(self.joints),
                'qos_offered': [str(o) for o in self.offered]}


def naming_findings(robots: list[str], cameras: list[CameraWatch]) -> list[str]:
    """Each robot that no camera's last frame named, with each camera's reason."""
    said = []
    for robot in robots:
        if any(camera.named.get(robot) == 'named' for camera in cameras):
            continue
        why = '; '.join(f'{camera.name}: {camera.named.get(robot, "no frame")}'
                        for camera in cameras)
        said.append(f'{robot}: named by no camera ({why}): check its code and that it is in '
                    'a field')
    return said


def _rounded(value: float | None, digits: int = 2) -> float | None:
    return None if value is None else round(value, digits)

