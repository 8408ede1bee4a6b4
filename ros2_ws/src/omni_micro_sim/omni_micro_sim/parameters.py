"""The robot and its motors: one validated, immutable parameter object each, in SI units.

Defaults are the paper's section 3.5 robot. Three values the paper does not state are pinned by
its two published results (docs/model.md, "Unstated parameters"): wheel 1 sits at 45 deg from
the robot's X axis, its cantilever is on the left of its rolling direction, and the chassis
radius used for the moment of inertia is 4.5 mm (the 9 mm chassis).
"""

from __future__ import annotations

import enum
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from omni_micro_sim.errors import ParameterError

# 50 Hz of simulated time: fine enough for the 0.05 s moves, coarse enough that a Python graph
# keeps up at a real-time factor of 10 on two cores.
DEFAULT_PERIOD_S = 0.02


class CantileverSide(enum.Enum):
    """Side of wheel 1 carrying its single-side cantilever, seen along its rolling direction."""

    LEFT = 1.0
    RIGHT = -1.0


def require_finite(name: str, value: float) -> float:
    """Return ``value`` as a float, or raise ParameterError naming ``name``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f'{name} must be a number, got {value!r}') from None
    if not math.isfinite(number):
        raise ParameterError(f'{name} must be finite, got {value!r}')
    return number


def require_finite_values(name: str, values: Any, count: int, what: str) -> tuple[float, ...]:
    """``values`` as a tuple of ``count`` finite floats, or ParameterError saying ``what``."""
    numbers = tuple(values)
    if len(numbers) != count:
        raise ParameterError(f'{name} must be {what}, got {list(numbers)!r}')
    return tuple(require_finite(f'{name}[{k}]', value) for k, value in enumerate(numbers))


def require_positive(name: str, value: float) -> float:
    number = require_finite(name, value)
    if number <= 0.0:
        raise ParameterError(f'{name} must be > 0, got {value!r}')
    return number


def require_non_negative(name: str, value: float) -> float:
    number = require_finite(name, value)
    if number < 0.0:
        raise ParameterError(f'{name} must be >= 0, got {value!r}')
    return number


# Positions of the fields in the float64 array the numba kernels take (one place defines them).
KERNEL_FIELDS = (
    'mass_kg',
    'gravity_m_s2',
    'mu_longitudinal',
    'mu_transverse',
    'friction_steepness_s_m',
    'wheel_distance_m',
    'wheel_radius_m',
    'signed_cantilever_offset_m',
    'moment_of_inertia_kg_m2',
    'wheel1_angle_rad',
    'wheel1_drive',
    'center_of_mass_x_m',
    'center_of_mass_y_m',
    'contact_radius_m',
    'pivot_coefficient',
)
KERNEL_INDEX = {name: index for index, name in enumerate(KERNEL_FIELDS)}


# The slowest steering the model integrates: a half turn of the wheels within a minute.
MAX_HALF_TURN_S = 60.0


@dataclass(frozen=True)
class SteeringParameters:
    """The steering motion (the paper's future work): motor, gear train and wheel pivot.

    The defaults are the paper's assumption, exact and instantaneous steering with point
    contacts; :data:`STEERING_PRESETS` names them ``ideal`` and gives ``realistic`` values
    (docs/model.md, "Steering dynamics", says where each comes from).

    Attributes
    ----------
    instantaneous : True: the wheels take the commanded angle at once and exactly (the paper);
        the motor, gear and backlash fields then play no part.
    motor_speed_rad_s, motor_acceleration_rad_s2 : the steering motor's speed and acceleration
        limits, at the motor's shaft; the wheels turn ``gear_ratio`` times slower.
    gear_ratio : the central gear to the wheels' big gears, 3:1 (section 2.1).
    backlash_rad : dead band of the hand-assembled gear train, as wheel steering angle: on a
        reversal the motor turns this far before the wheels follow.
    step_rad : wheel steering angle per motor (micro)step; the commanded angle is rounded to a
        whole number of steps (0: continuous).
    contact_radius_m : radius a of each wheel's contact patch; 0 (point contacts) means no
        pivot friction torque.
    pivot_coefficient : the full-slip pivot torque is pivot_coefficient * mu_T * a * N
        (2/3 for a uniformly loaded patch, 2/5 for a Hertzian one).
    """

    instantaneous: bool = True
    motor_speed_rad_s: float = 3.0 * math.pi
    motor_acceleration_rad_s2: float = 30.0 * math.pi
    gear_ratio: float = 3.0
    backlash_rad: float = 0.0
    step_rad: float = 0.0
    contact_radius_m: float = 0.0
    pivot_coefficient: float = 2.0 / 3.0

    def __post_init__(self) -> None:
        if not isinstance(self.instantaneous, (bool, np.bool_)):
            raise ParameterError(
                f'steering.instantaneous must be a bool, got {self.instantaneous!r}')
        object.__setattr__(self, 'instantaneous', bool(self.instantaneous))
        for name in ('motor_speed_rad_s', 'motor_acceleration_rad_s2', 'gear_ratio'):
            object.__setattr__(self, name,
                               require_positive(f'steering.{name}', getattr(self, name)))
        for name in ('backlash_rad', 'step_rad', 'contact_radius_m', 'pivot_coefficient'):
            object.__setattr__(self, name,
                               require_non_negative(f'steering.{name}', getattr(self, name)))
        if self.backlash_rad >= math.pi / 2:
            raise ParameterError(
                f'steering.backlash_rad must be below 90 deg, got {self.backlash_rad!r} rad')
        if self.step_rad >= math.pi / 2:
            raise ParameterError(
                f'steering.step_rad must be below 90 deg, got {self.step_rad!r} rad')
        if self.pivot_coefficient > 1.0:
            raise ParameterError(f'steering.pivot_coefficient must be in [0, 1] (2/3 for a '
                                 f'uniform patch), got {self.pivot_coefficient!r}')
        # What the steering model can integrate: a half turn of the wheels at the limits (a
        # trapezoid: the travel at the top speed, and the ramps) in at most a minute; 1e300
        # for a gear ratio made it 1e299 s, and the knots of the move no longer increased.
        half_turn_s = math.pi / self.rate_rad_s + self.rate_rad_s / self.acceleration_rad_s2
        if not half_turn_s <= MAX_HALF_TURN_S:
            raise ParameterError(
                f'steering: a half turn of the wheels would take {half_turn_s:.3g} s with '
                f'motor_speed_rad_s {self.motor_speed_rad_s!r}, motor_acceleration_rad_s2 '
                f'{self.motor_acceleration_rad_s2!r} and gear_ratio {self.gear_ratio!r}: at '
                f'most {MAX_HALF_TURN_S:g} s (the realistic preset takes 1.1 s)')

    @property
    def rate_rad_s(self) -> float:
        """The wheels' steering speed limit."""
        return self.motor_speed_rad_s / self.gear_ratio

    @property
    def acceleration_rad_s2(self) -> float:
        """The wheels' steering acceleration limit."""
        return self.motor_acceleration_rad_s2 / self.gear_ratio

    def replace(self, **changes: Any) -> SteeringParameters:
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ParameterError(
                f'unknown steering parameter(s): {", ".join(sorted(unknown))}')
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return SteeringParameters(**values)


# Named sets of steering values. ``ideal`` is the paper; ``realistic`` the documented estimates
# of the real robot (docs/model.md, "Steering dynamics": source or stated guess of each).
STEERING_PRESETS = {
    'ideal': SteeringParameters(),
    'realistic': SteeringParameters(
        instantaneous=False,
        # 180 deg/s of steering, reached in 0.1 s: a guess for a 3 mm stepper at 3:1.
        motor_speed_rad_s=3.0 * math.pi,
        motor_acceleration_rad_s2=30.0 * math.pi,
        gear_ratio=3.0,
        # Hand-assembled gears: a guess of 1 deg of play at the wheels.
        backlash_rad=math.radians(1.0),
        # 0.83 deg of steering per full step (Opt. Precision Eng. 16(6), 2008), 16 microsteps.
        step_rad=math.radians(0.83) / 16.0,
        # Between a Hertzian point (6 um) and a flat rim's line contact (~150 um): a guess.
        contact_radius_m=50e-6,
        pivot_coefficient=2.0 / 3.0,
    ),
}


def steering_preset(name: str) -> SteeringParameters:
    """The steering values named ``name`` (a key of :data:`STEERING_PRESETS`)."""
    try:
        return STEERING_PRESETS[name]
    except KeyError:
        raise ParameterError(f'steering must be one of {sorted(STEERING_PRESETS)}, '
                             f'got {name!r}') from None


@dataclass(frozen=True)
class RobotParameters:
    """Physical parameters of the tri-wheeled microrobot (eqs. 1-13).

    Attributes
    ----------
    mass_kg : m, 2.8 g.
    gravity_m_s2 : g; the weight m*g is shared equally by the three wheels (eq. 11).
    mu_longitudinal, mu_transverse : mu_L, mu_T, 0.21 (eq. 10).
    friction_steepness_s_m : p in mu(Vs) = mu*(2/pi)*atan(p*Vs), Vs in m/s; 1000 (eq. 10).
    wheel_distance_m : L, from the chassis centre to each wheel centre, 4.15 mm.
    wheel_radius_m : r, 1.65 mm.
    cantilever_offset_m : d1, wheel 1 centre to its cantilever along the axle, 1 mm (eq. 12).
    cantilever_side : which side of wheel 1 the cantilever is on.
    chassis_radius_m : R in I = m*R^2/2 (eq. 13).
    wheel1_angle_rad : where wheel 1 sits, from the robot's X axis; wheels 2 and 3 follow at
        +120 deg and +240 deg.
    wheel_offsets_rad : assembly offsets xi_k of the three wheels' rolling directions from the
        common steering angle theta (section 3.5.2).
    wheel1_active : False makes wheel 1 passive: it rolls freely, so its contact carries no
        longitudinal force (and hence no cantilever torque); transverse friction remains.
    center_of_mass_m : where the centre of mass sits from the chassis centre, body frame (x, y);
        off the centre, the wheels' normal forces follow from statics instead of m*g/3 each.
    steering : the steering motion (:class:`SteeringParameters`; the default is the paper's).
    """

    mass_kg: float = 2.8e-3
    gravity_m_s2: float = 9.80665
    mu_longitudinal: float = 0.21
    mu_transverse: float = 0.21
    friction_steepness_s_m: float = 1000.0
    wheel_distance_m: float = 4.15e-3
    wheel_radius_m: float = 1.65e-3
    cantilever_offset_m: float = 1.0e-3
    cantilever_side: CantileverSide = CantileverSide.LEFT
    chassis_radius_m: float = 4.5e-3
    wheel1_angle_rad: float = math.radians(45.0)
    wheel_offsets_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wheel1_active: bool = True
    center_of_mass_m: tuple[float, float] = (0.0, 0.0)
    steering: SteeringParameters = SteeringParameters()

    def __post_init__(self) -> None:
        for name in ('mass_kg', 'gravity_m_s2', 'friction_steepness_s_m', 'wheel_distance_m',
                     'wheel_radius_m', 'chassis_radius_m'):
            object.__setattr__(self, name, require_positive(name, getattr(self, name)))
        for name in ('mu_longitudinal', 'mu_transverse', 'cantilever_offset_m'):
            object.__setattr__(self, name, require_non_negative(name, getattr(self, name)))
        object.__setattr__(
            self, 'wheel1_angle_rad', require_finite('wheel1_angle_rad', self.wheel1_angle_rad))
        if not isinstance(self.cantilever_side, CantileverSide):
            try:
                side = CantileverSide[str(self.cantilever_side).upper()]
            except KeyError:
                raise ParameterError(
                    f"cantilever_side must be 'left' or 'right', got {self.cantilever_side!r}"
                ) from None
            object.__setattr__(self, 'cantilever_side', side)
        checked = require_finite_values('wheel_offsets_rad', self.wheel_offsets_rad, 3,
                                        '3 values (one per wheel)')
        for k, value in enumerate(checked):
            if abs(value) >= math.pi / 2:
                raise ParameterError(
                    f'wheel_offsets_rad[{k}] must be within +-90 deg, got {value!r} rad')
        object.__setattr__(self, 'wheel_offsets_rad', checked)
        if not isinstance(self.wheel1_active, (bool, np.bool_)):
            raise ParameterError(f'wheel1_active must be a bool, got {self.wheel1_active!r}')
        object.__setattr__(self, 'wheel1_active', bool(self.wheel1_active))
        centre = require_finite_values('center_of_mass_m', self.center_of_mass_m, 2,
                                       '[x, y] in metres')
        # Statics needs the centre of mass inside the triangle of the contacts, or a wheel
        # would have to pull on the ground.
        if math.hypot(*centre) >= 0.5 * self.wheel_distance_m:
            raise ParameterError(
                f'center_of_mass_m must lie within L/2 = {0.5 * self.wheel_distance_m:g} m of '
                f'the centre (inside the wheels), got {list(centre)!r}')
        object.__setattr__(self, 'center_of_mass_m', centre)
        if not isinstance(self.steering, SteeringParameters):
            raise ParameterError(
                f'steering must be SteeringParameters, got {self.steering!r}')
        # A contact patch wider than the wheel is not a wheel's: 1 m made the robot slide 20 mm.
        if self.steering.contact_radius_m >= self.wheel_radius_m:
            raise ParameterError(
                f'steering.contact_radius_m must be below the wheel radius '
                f'{self.wheel_radius_m!r} m, got {self.steering.contact_radius_m!r}')
        # Each value finite is not enough: I = m R^2 / 2 can still overflow (found by
        # tests/sim/test_properties.py with R = 1e154 m).
        try:
            inertia = self.moment_of_inertia_kg_m2
        except OverflowError:
            inertia = math.inf
        if not math.isfinite(inertia) or inertia <= 0.0:
            raise ParameterError(
                f'the moment of inertia m*R^2/2 from mass_kg={self.mass_kg!r} and '
                f'chassis_radius_m={self.chassis_radius_m!r} must be a finite number > 0, '
                f'got {inertia!r}')

    @property
    def moment_of_inertia_kg_m2(self) -> float:
        """I = m*R^2/2: the chassis is a disc and the wheels weigh much less (section 3.4)."""
        return 0.5 * self.mass_kg * self.chassis_radius_m ** 2

    @property
    def signed_cantilever_offset_m(self) -> float:
        return self.cantilever_side.value * self.cantilever_offset_m

    @property
    def wheel1_drive(self) -> float:
        return 1.0 if self.wheel1_active else 0.0

    @property
    def center_of_mass_x_m(self) -> float:
        return self.center_of_mass_m[0]

    @property
    def center_of_mass_y_m(self) -> float:
        return self.center_of_mass_m[1]

    @property
    def contact_radius_m(self) -> float:
        return self.steering.contact_radius_m

    @property
    def pivot_coefficient(self) -> float:
        return self.steering.pivot_coefficient

    def as_kernel_array(self) -> np.ndarray:
        """The parameters in the order of :data:`KERNEL_FIELDS`, for the numba kernels."""
        return np.array([float(getattr(self, name)) for name in KERNEL_FIELDS], dtype=np.float64)

    def replace(self, **changes: Any) -> RobotParameters:
        """A copy with ``changes`` applied (and validated)."""
        unknown = set(changes) - {f.name for f in fields(self)}
        if unknown:
            raise ParameterError(f'unknown robot parameter(s): {", ".join(sorted(unknown))}')
        values = {f.name: getattr(self, f.name) for f in fields(self)}
        values.update(changes)
        return RobotParameters(**values)

    @classmethod
    def from_mapping(cls, values: Mapping[str, Any]) -> RobotParameters:
        """Build from a flat mapping such as a ROS parameter dictionary.

        The steering's values come as ``steering.<name>`` keys, as :func:`robot_parameter_values`
        gives them.
        """
        flat = dict(values)
        steering = {key.removeprefix(STEERING_PREFIX): flat.pop(key) for key in list(flat)
                    if key.startswith(STEERING_PREFIX)}
        robot = cls().replace(**flat)
        if steering:
            robot = robot.replace(steering=robot.steering.replace(**steering))
        return robot


STEERING_PREFIX = 'steering.'


def robot_parameter_values(robot: RobotParameters) -> dict[str, object]:
    """The robot as ROS parameter values: enums by name, tuples as lists, the steering's
    values as ``steering.<name>``."""
    values: dict[str, object] = {}
    for field in fields(robot):
        value = getattr(robot, field.name)
        if field.name == 'cantilever_side':
            value = value.name.lower()
        elif field.name in ('wheel_offsets_rad', 'center_of_mass_m'):
            value = [float(v) for v in value]
        elif field.name == 'steering':
            for steering_field in fields(value):
                values[STEERING_PREFIX + steering_field.name] = getattr(value,
                                                                        steering_field.name)
            continue
        values[field.name] = value
    return values


@dataclass(frozen=True)
class MotorLimits:
    """Wheel motor speed profile of section 3.5: ramp to a cruise speed, hold, ramp down."""

    cruise_speed_rad_s: float = 8.7
    acceleration_rad_s2: float = 50.0
    deceleration_rad_s2: float = 50.0
    max_speed_rad_s: float = 8.7

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, require_positive(f.name, getattr(self, f.name)))
        if self.cruise_speed_rad_s > self.max_speed_rad_s:
            raise ParameterError(
                f'cruise_speed_rad_s ({self.cruise_speed_rad_s}) must not exceed '
                f'max_speed_rad_s ({self.max_speed_rad_s})')
