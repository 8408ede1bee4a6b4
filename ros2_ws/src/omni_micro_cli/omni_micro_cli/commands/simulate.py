"""`omni-micro simulate`: one open-loop move through the slip core (section 3.5)."""

from __future__ import annotations

import argparse
import math
import time

from omni_micro_cli.arguments import (
    add_steering_argument,
    float_list,
    non_negative_float,
    number_in,
)
from omni_micro_cli.errors import UsageError
from omni_micro_cli.outputs import print_json
from omni_micro_sim.parameters import MotorLimits, RobotParameters, steering_preset

# A steering angle as the wheel contract bounds it (omni_micro_sim.wheel_trajectory): beyond a
# turn or two a float holds no direction (1e20 deg "steered" in no time and drifted 17 mm).
steering_degrees = number_in(-360.0, 360.0)
# The motors of section 3.5, as the help says them.
_MOTORS = MotorLimits()


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'simulate',
        description='Run one open-loop move of the paper\'s section 3.5 from rest at the origin '
                    f'with phi = 0: ramp to {_MOTORS.cruise_speed_rad_s:g} rad/s at '
                    f'{_MOTORS.acceleration_rad_s2:g} rad/s^2, hold, ramp down, so that the '
                    f'wheels turn by {_MOTORS.cruise_speed_rad_s:g} rad/s times DURATION; then '
                    'wait until the robot is '
                    'at rest. The drift is the distance from where a slip-free robot would stop. '
                    'With --steering realistic and --steer-from-deg the wheels first steer '
                    'from that angle (the chassis turns against the steering); --duration 0 '
                    'is then a steering-only move.')
    parser.add_argument('--theta-deg', type=steering_degrees, required=True, metavar='DEG',
                        help='steering (direction) angle theta in the robot frame, degrees '
                             '(within +-360, the wheel contract\'s +-2 pi)')
    parser.add_argument('--duration', type=non_negative_float, required=True, metavar='S',
                        help='move time t in seconds (wheel rotation = '
                             f'{_MOTORS.cruise_speed_rad_s:g} rad/s * t); 0 with '
                             '--steer-from-deg: steer only')
    parser.add_argument('--xi-deg', type=float_list(3, 'wheel offsets in degrees'),
                        default=(0.0, 0.0, 0.0), metavar='X1,X2,X3',
                        help='assembly offsets of wheels 1,2,3 in degrees (default 0,0,0; '
                             'the paper\'s Fig. 8 robot is 0,3,2)')
    parser.add_argument('--passive-wheel1', action='store_true',
                        help='wheel 1 rolls freely instead of being driven (section 3.5.1)')
    add_steering_argument(parser)
    parser.add_argument('--steer-from-deg', type=steering_degrees, metavar='A',
                        help='the wheels\' steering angle before the move, degrees (default: '
                             'already at theta, as the paper has it)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object (mm, deg) alone')
    parser.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.duration == 0.0 and args.steer_from_deg is None:
        raise UsageError('--duration 0 is a steering-only move: give --steer-from-deg too '
                         '(or a duration > 0 s)')
    params = RobotParameters(
        wheel_offsets_rad=(math.radians(args.xi_deg[0]), math.radians(args.xi_deg[1]),
                           math.radians(args.xi_deg[2])),
        wheel1_active=not args.passive_wheel1, steering=steering_preset(args.steering))
    steer_from = None if args.steer_from_deg is None else math.radians(args.steer_from_deg)
    started = time.perf_counter()
    from omni_micro_sim.open_loop import simulate_open_loop  # numba: only when a move runs

    result = simulate_open_loop(params, math.radians(args.theta_deg), args.duration,
                                steer_from_rad=steer_from)
    elapsed = time.perf_counter() - started
    final = result.final_state
    summary = {
        'x_mm': final.x_m * 1e3,
        'y_mm': final.y_m * 1e3,
        'phi_deg': math.degrees(final.phi_rad),
        'drift_mm': result.drift_m * 1e3,
        'ideal_x_mm': result.ideal_stop_m[0] * 1e3,
        'ideal_y_mm': result.ideal_stop_m[1] * 1e3,
        'theta_deg': args.theta_deg,
        'duration_s': args.duration,
        'xi_deg': list(args.xi_deg),
        'passive_wheel1': args.passive_wheel1,
        'steering': args.steering,
        'steer_from_deg': args.steer_from_deg,
        'steering_time_s': result.steering_time_s,
        'final_steering_deg': math.degrees(result.final_steering_rad),
        'profile_end_s': result.profile_end_s,
        'rest_time_s': result.rest_time_s,
        'compute_time_s': elapsed,
    }
    if args.json:
        print_json(summary)
        return 0
    print(f'open-loop move: theta {args.theta_deg:g} deg, t = {args.duration:g} s, '
          f'xi = {",".join(f"{v:g}" for v in args.xi_deg)} deg, wheel 1 '
          f'{"passive" if args.passive_wheel1 else "active"}, {args.steering} steering')
    if args.steer_from_deg is not None:
        print(f'  steered from {args.steer_from_deg:g} deg to '
              f'{summary["final_steering_deg"]:.4f} deg in {result.steering_time_s:.3f} s')
    print(f'  ideal stop   ({summary["ideal_x_mm"]:.4f}, {summary["ideal_y_mm"]:.4f}) mm')
    print(f'  final pose   ({summary["x_mm"]:.4f}, {summary["y_mm"]:.4f}) mm, '
          f'phi {summary["phi_deg"]:.4f} deg')
    print(f'  drift        {summary["drift_mm"]:.4f} mm')
    print(f'  wheels stop at {result.profile_end_s:.3f} s, robot at rest at '
          f'{result.rest_time_s:.3f} s (computed in {elapsed * 1e3:.1f} ms)')
    return 0
