"""`omni-micro bench`: speed of the slip core against a solve_ivp reference, measured in one run.

The reference is what a careful user would write without this project: scipy's
``solve_ivp(method='LSODA', rtol=1e-9)`` on the same equations with a plain-Python right-hand side
(the kernels run as Python in a child process with NUMBA_DISABLE_JIT=1).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
import time
from typing import TYPE_CHECKING

import numpy as np

from omni_micro_cli.arguments import positive_float, whole_number_in
from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_cli.outputs import print_json
from omni_micro_sim import paper

if TYPE_CHECKING:
    from omni_micro_sim.parameters import RobotParameters



def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bench',
        description='Time the slip core on the 7 s open-loop move of Fig. 11 against '
                    "solve_ivp(method='LSODA', rtol=1e-9) with a plain-Python right-hand side, "
                    'and a batch of open-loop moves (a fine Fig. 7 sweep). Prints figures; '
                    'targets: >= 50x faster than the reference, 1000 moves in < 10 s.')
    parser.add_argument('--batch',
                        type=whole_number_in(1, 1_000_000), default=1000, metavar='N',
                        help='moves in the batch (default 1000)')
    parser.add_argument('--repeats',
                        type=whole_number_in(1, 10_000), default=30, metavar='N',
                        help='timed repeats of the single run; the median is reported '
                             '(default 30)')
    parser.add_argument('--reference-timeout', type=positive_float, default=600.0, metavar='S',
                        help='give up on the reference after S seconds (default 600)')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the rest on stderr)')
    parser.set_defaults(handler=run)


def _fig11() -> tuple[RobotParameters, float, float]:

    scenario = paper.FIG11_OPEN_LOOP
    return scenario.robot(), math.radians(scenario.steering_deg), scenario.duration_s


def reference_main() -> None:
    """Child process: the LSODA reference, kernels running as plain Python (median of 3)."""
    from omni_micro_sim import move_profile
    from omni_micro_sim.reference import solve_ivp_reference
    params, steering, duration = _fig11()
    end_time = float(sys.argv[1])
    profile = move_profile(duration)
    timings = []
    for _ in range(3):
        started = time.perf_counter()
        state, calls = solve_ivp_reference(params, steering, profile, end_time, method='LSODA',
                                           rtol=1e-9, atol=1e-13)
        timings.append(time.perf_counter() - started)
    print(json.dumps({'seconds': float(np.median(timings)), 'rhs_calls': calls, 'x_m': state.x_m,
                      'y_m': state.y_m, 'phi_rad': state.phi_rad}))


def _log(message: str) -> None:
    print(f'[bench] {message}', file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    from omni_micro_sim import simulate_open_loop
    from omni_micro_sim.open_loop import simulate_open_loop_batch

    if args.batch < 1 or args.repeats < 1:
        raise UsageError(f'--batch and --repeats must be >= 1, got {args.batch}, {args.repeats}')
    params, steering, duration = _fig11()

    started = time.perf_counter()
    result = simulate_open_loop(params, steering, duration)
    first_call = time.perf_counter() - started
    simulate_open_loop_batch(params, np.zeros(2), duration)   # load the parallel kernel too
    _log(f'first call (numba compile or cache load): {first_call:.2f} s')
    timings = []
    for _ in range(args.repeats):
        started = time.perf_counter()
        result = simulate_open_loop(params, steering, duration)
        timings.append(time.perf_counter() - started)
    core_single = float(np.median(timings))
    _log(f'core, one 7 s move: median {core_single * 1e3:.1f} ms of {args.repeats}')

    _log(f'reference: LSODA rtol 1e-9, plain-Python rhs (up to {args.reference_timeout:g} s)...')
    environment = dict(os.environ, NUMBA_DISABLE_JIT='1')
    try:
        child = subprocess.run(
            [sys.executable, '-c',
             'from omni_micro_cli.commands.bench import reference_main; reference_main()',
             repr(result.rest_time_s)], env=environment, capture_output=True, text=True,
            timeout=args.reference_timeout, check=True)
    except subprocess.TimeoutExpired:
        raise RunFailed(f'the reference did not finish within --reference-timeout '
                        f'{args.reference_timeout:g} s (it takes tens of seconds here; give '
                        'more)') from None
    except subprocess.CalledProcessError as error:
        raise RunFailed(f'the reference failed: {error.stderr.strip()[-300:]}') from None
    reference = json.loads(child.stdout.strip().splitlines()[-1])
    _log(f'reference: {reference["seconds"]:.2f} s, {reference["rhs_calls"]} rhs calls')
    difference_m = math.hypot(result.final_state.x_m - reference['x_m'],
                              result.final_state.y_m - reference['y_m'])

    offsets = np.linspace(-10.0, 10.0, args.batch)
    robots = [params.replace(wheel_offsets_rad=(0.0, math.radians(v), math.radians(v)))
              for v in offsets]
    goal = np.array(paper.FIG7_GOAL_M)
    duration7 = paper.duration_for_distance(float(np.hypot(*goal)))
    _log(f'batch: {args.batch} open-loop moves (Fig. 7 sweep, xi -10..10 deg)...')
    started = time.perf_counter()
    simulate_open_loop_batch(robots, np.full(args.batch, math.atan2(goal[1], goal[0])), duration7)
    batch_seconds = time.perf_counter() - started
    batch_7s_seconds = None
    if args.batch >= 100:
        started = time.perf_counter()
        simulate_open_loop_batch(params, np.radians(np.linspace(0.0, 360.0, 100)), duration)
        batch_7s_seconds = time.perf_counter() - started

    figures = {
        'core_single_run_s': core_single,
        'core_first_call_s': first_call,
        'reference_lsoda_s': reference['seconds'],
        'reference_rhs_calls': reference['rhs_calls'],
        'speedup_vs_reference': reference['seconds'] / core_single,
        'final_position_difference_um': difference_m * 1e6,
        'batch_moves': args.batch,
        'batch_s': batch_seconds,
        'batch_moves_per_s': args.batch / batch_seconds,
        'batch_100_seven_second_moves_s': batch_7s_seconds,
        'cores': os.cpu_count(),
    }
    if args.json:
        print_json(figures)
        return 0
    print('omni-micro bench (7 s open-loop move of Fig. 11; batch = Fig. 7 sweep of 1 s moves)')
    print(f'  reference solve_ivp LSODA rtol 1e-9, Python rhs : '
          f'{reference["seconds"]:8.3f} s (median of 3)')
    print(f'  slip core (numba RK4), one run                 : {core_single * 1e3:8.2f} ms')
    print(f'  speed-up                                       : '
          f'{figures["speedup_vs_reference"]:8.1f} x  (target >= 50)')
    print(f'  final position core vs reference               : {difference_m * 1e6:8.4f} um')
    print(f'  batch of {args.batch} moves                        : '
          f'{batch_seconds:8.2f} s  (target < 10 s)')
    if batch_7s_seconds is not None:
        print(f'  batch of 100 seven-second moves                : {batch_7s_seconds:8.2f} s')
    print(f'  first call in a new process (compile/cache)    : {first_call:8.2f} s')
    return 0
