"""The paper's rule, the model-based mode and the servo, compared (``omni-micro
compare-controllers``).

Seeded cases on the micro platform, each run by the three modes through the in-process twin
(the graph's loop in one process): half drive (0,0) -> (100,0) mm, half drive from a random
start in the macro field to a random goal inside the micro field; every robot has random
assembly offsets xi2, xi3 in [-5, 5] deg, which neither the model mode nor the servo knows
(they start from none). With --steering realistic every robot also steers through the
realistic preset with a backlash drawn in [0, 2] deg, which they do not know either (they start
from the preset's 1 deg).
"""

from __future__ import annotations

import math
import statistics
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from omni_micro_control.feedback import Outcome
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_sim.parameters import RobotParameters, steering_preset
from omni_micro_sim.state import RobotState

if TYPE_CHECKING:
    from omni_micro_studies.twin import ClosedLoopResult


OFFSET_RANGE_DEG = 5.0
# Hand-assembled gears: from none to twice the realistic preset's 1 deg (a stated guess).
BACKLASH_RANGE_DEG = (0.0, 2.0)
MICRO_GOAL_HALF_WIDTH_M = 0.8e-3     # goals well inside the 2 mm micro field
# The modes compared, and how the table and the figure name them.
MODES = {'paper': "paper's rule", 'model': 'model-based', 'servo': 'servo'}


@dataclass(frozen=True)
class Case:
    index: int
    xi2_deg: float
    xi3_deg: float
    start: tuple[float, float, float]     # m, m, rad
    goal_m: tuple[float, float]
    seed: int
    steering: str = 'ideal'
    backlash_deg: float = 0.0


def make_cases(count: int, seed: int, steering: str = 'ideal') -> list[Case]:
    cases = []
    for index in range(count):
        rng = np.random.default_rng([seed, index])
        xi2, xi3 = rng.uniform(-OFFSET_RANGE_DEG, OFFSET_RANGE_DEG, 2)
        # Drawn after everything else, so that ideal cases stay the cases they always were.
        backlash = 0.0
        if index % 2 == 0:
            start, goal = (0.0, 0.0, 0.0), (0.1, 0.0)
        else:
            start = (float(rng.uniform(0.0, 0.04)), float(rng.uniform(-0.03, 0.03)),
                     float(rng.uniform(-math.pi, math.pi)))
            offset = rng.uniform(-MICRO_GOAL_HALF_WIDTH_M, MICRO_GOAL_HALF_WIDTH_M, 2)
            goal = (0.1 + float(offset[0]), float(offset[1]))
        if steering != 'ideal':
            backlash = float(rng.uniform(*BACKLASH_RANGE_DEG))
        cases.append(Case(index, float(xi2), float(xi3), start, goal, seed * 100_000 + index,
                          steering, backlash))
    return cases


def _run(case: Case, mode: str, tolerance_m: float) -> ClosedLoopResult:
    from omni_micro_control.servo_config import ServoConfig
    from omni_micro_studies.twin import run_closed_loop, run_servo

    preset = steering_preset(case.steering)
    robot = RobotParameters(
        wheel_offsets_rad=(0.0, math.radians(case.xi2_deg), math.radians(case.xi3_deg)),
        steering=preset.replace(backlash_rad=math.radians(case.backlash_deg)))
    # The model knows the steering's form (the preset), not this robot's backlash or offsets.
    if mode == 'servo':
        return run_servo(case.goal_m, robot=robot, seed=case.seed, start=RobotState(*case.start),
                         config=ServoConfig(tolerance_m=tolerance_m),
                         model_robot=RobotParameters(steering=preset))
    return run_closed_loop(case.goal_m, robot=robot, seed=case.seed,
                           start=RobotState(*case.start),
                           config=FeedbackConfig(mode=mode, tolerance_m=tolerance_m),
                           model_robot=RobotParameters(steering=preset))


def run_case(case: Case, tolerance_m: float) -> dict[str, object]:
    """Every mode on one case; the row of the results (a servo's periods are its moves)."""
    from omni_micro_control.model_based import ModelBasedPlanner
    from omni_micro_studies.twin import ServoResult

    row: dict[str, object] = {**asdict(case)}
    for mode in MODES:
        began = time.perf_counter()
        result = _run(case, mode, tolerance_m)
        row[f'{mode}_outcome'] = result.outcome.value
        row[f'{mode}_periods'] = result.periods
        if isinstance(result, ServoResult):
            row['servo_stops'] = result.stops
            row['servo_replans'] = result.replans
        row[f'{mode}_deviation_um'] = result.deviation_m * 1e6
        row[f'{mode}_sim_time_s'] = result.sim_time_s
        row[f'{mode}_wall_s'] = time.perf_counter() - began
        planner = result.planner
        if isinstance(planner, ModelBasedPlanner):
            log = planner.log
            row['model_rules'] = [move.rule for move in result.moves]
            row['model_fallbacks'] = len(log.fallbacks)
            for label, index in (('first_move', 0), ('second_move', 1)):
                if len(log.estimates) > index:
                    row[f'xi2_error_deg_{label}'] = math.degrees(
                        log.estimates[index]['xi2']) - case.xi2_deg
                    row[f'xi3_error_deg_{label}'] = math.degrees(
                        log.estimates[index]['xi3']) - case.xi3_deg
            if log.estimates and 'backlash' in log.estimates[-1]:
                row['backlash_error_deg_last'] = math.degrees(
                    log.estimates[-1]['backlash']) - case.backlash_deg
            row['plan_wall_s'] = log.plan_wall_s
            row['fit_wall_s'] = log.fit_wall_s
        if case.index == 0:
            row[f'{mode}_route_m'] = result.route_m[:, 1:].tolist()
    return row


def not_worse(row: dict[str, object], tolerance_um: float) -> bool:
    """The model mode did no worse than the paper's rule on this case: it reached whenever
    the paper did, in no more periods, ending within the tolerance or no farther."""
    if row['paper_outcome'] == Outcome.REACHED.value and \
            row['model_outcome'] != Outcome.REACHED.value:
        return False
    deviation = float(row['model_deviation_um'])   # type: ignore[arg-type]
    return (int(row['model_periods']) <= int(row['paper_periods'])   # type: ignore[call-overload]
            and (deviation <= tolerance_um
                 or deviation <= float(row['paper_deviation_um'])))  # type: ignore[arg-type]


def summarise(rows: list[dict], tolerance_um: float) -> dict[str, object]:
    def share(values: list[bool]) -> float:
        return 100.0 * sum(values) / max(1, len(values))

    def errors(key: str) -> list[float]:
        return [abs(row[key]) for row in rows if key in row]

    plans = [wall for row in rows for wall in row['plan_wall_s']]
    fits = [wall for row in rows for wall in row['fit_wall_s']]
    summary: dict[str, object] = {'cases': len(rows), 'tolerance_um': tolerance_um,
                                  'steering': rows[0].get('steering', 'ideal')}
    for mode in MODES:
        deviations = [row[f'{mode}_deviation_um'] for row in rows]
        periods = [row[f'{mode}_periods'] for row in rows]
        times = [row[f'{mode}_sim_time_s'] for row in rows]
        summary[mode] = {
            'reached_percent': share([row[f'{mode}_outcome'] == 'reached' for row in rows]),
            'within_tolerance_percent': share([d <= tolerance_um for d in deviations]),
            'median_periods': statistics.median(periods), 'max_periods': max(periods),
            'median_deviation_um': statistics.median(deviations),
            'max_deviation_um': max(deviations),
            'median_sim_time_s': statistics.median(times), 'max_sim_time_s': max(times),
            **({'max_stops': max(row['servo_stops'] for row in rows)} if mode == 'servo'
               else {}),
        }
    summary['model_not_worse_percent'] = share([not_worse(row, tolerance_um) for row in rows])
    summary['model_cases_with_fallback'] = sum(1 for row in rows if row['model_fallbacks'])
    for label in ('first_move', 'second_move'):
        both = errors(f'xi2_error_deg_{label}') + errors(f'xi3_error_deg_{label}')
        summary[f'offset_error_deg_{label}'] = {
            'max': max(both), 'median': statistics.median(both),
            'within_0.1_deg_percent': share([e <= 0.1 for e in both])}
    backlash = errors('backlash_error_deg_last')
    if backlash:
        summary['backlash_error_deg_last'] = {'median': statistics.median(backlash),
                                              'max': max(backlash)}
    summary['plan_wall_ms'] = {'median': 1e3 * statistics.median(plans),
                               'max': 1e3 * max(plans)}
    summary['refit_wall_ms'] = {'median': 1e3 * statistics.median(fits),
                                'max': 1e3 * max(fits)}
    return summary


def table(summary: dict) -> str:
    first, second = summary['offset_error_deg_first_move'], summary['offset_error_deg_second_move']

    def each(template: str) -> str:
        """A row's cells, one per mode: ``template`` filled from the mode's summary."""
        return ' | '.join(template.format(**summary[mode]) for mode in MODES)

    def model_only(text: str) -> str:
        return f'- | {text} | -'

    rows = [
        (f"{summary['cases']} cases, tolerance {summary['tolerance_um']:g} um, "
         f"{summary['steering']} steering", ' | '.join(MODES.values())),
        ('reached', each('{reached_percent:.0f} %')),
        ('final deviation <= tolerance', each('{within_tolerance_percent:.0f} %')),
        ('periods (servo: moves): median (max)', each('{median_periods:g} ({max_periods})')),
        ('stops: max', f"- | - | {summary['servo']['max_stops']}"),
        ('final deviation: median (max)',
         each('{median_deviation_um:.3f} um ({max_deviation_um:.3f} um)')),
        ('simulated time: median (worst)',
         each('{median_sim_time_s:.2f} s ({max_sim_time_s:.2f} s)')),
        ("model-based no worse than the paper's rule on the same case",
         model_only(f"{summary['model_not_worse_percent']:.0f} %")),
        ("cases with a fall-back to the paper's rule",
         model_only(str(summary['model_cases_with_fallback']))),
        ('xi2, xi3 error after the first (long) move: median, max',
         model_only(f"{first['median']:.3f}, {first['max']:.3f} deg "
                    f"({first['within_0.1_deg_percent']:.0f} % within 0.1 deg)")),
        ('xi2, xi3 error after the second move: median, max',
         model_only(f"{second['median']:.4f}, {second['max']:.4f} deg "
                    f"({second['within_0.1_deg_percent']:.0f} % within 0.1 deg)")),
    ]
    backlash = summary.get('backlash_error_deg_last')
    if backlash:
        rows.append(('backlash error after the last move: median, max',
                     model_only(f"{backlash['median']:.3f}, {backlash['max']:.3f} deg")))
    rows += [
        ('wall time per plan: median, max',
         model_only(f"{summary['plan_wall_ms']['median']:.1f}, "
                    f"{summary['plan_wall_ms']['max']:.1f} ms")),
        ('wall time per refit (after each stop): median, max',
         model_only(f"{summary['refit_wall_ms']['median']:.1f}, "
                    f"{summary['refit_wall_ms']['max']:.1f} ms")),
    ]
    lines = [f'| {label} | {cells} |' for label, cells in rows]
    lines.insert(1, '|---|---|---|---|')
    return '\n'.join(lines) + '\n'


def figure(path: Path, rows: list[dict], tolerance_um: float) -> None:
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    bins = np.arange(0.5, max(row['paper_periods'] for row in rows) + 1.5)
    for mode, colour in zip(MODES, ('tab:orange', 'tab:blue', 'tab:green'), strict=True):
        label = MODES[mode]
        axes[0].hist([row[f'{mode}_periods'] for row in rows], bins=bins, color=colour,
                     alpha=0.7, label=label)
        axes[1].hist([row[f'{mode}_deviation_um'] for row in rows],
                     bins=np.linspace(0, tolerance_um * 1.2, 25), color=colour, alpha=0.6,
                     label=label)
        route = np.array(rows[0][f'{mode}_route_m'])
        axes[2].plot(route[:, 0] * 1e3, route[:, 1] * 1e3, color=colour, label=label)
    axes[0].set(xlabel='periods to the goal', ylabel='cases', title='periods')
    axes[1].axvline(tolerance_um, color='k', linestyle='--', label='tolerance')
    axes[1].set(xlabel='final deviation (um)', ylabel='cases', title='final deviation')
    first = rows[0]
    axes[2].plot([first['start'][0] * 1e3, first['goal_m'][0] * 1e3],
                 [first['start'][1] * 1e3, first['goal_m'][1] * 1e3], 'k:', label='ideal')
    axes[2].set(xlabel='x (mm)', ylabel='y (mm)',
                title=f"case 0: xi2 {first['xi2_deg']:.2f}, xi3 {first['xi3_deg']:.2f} deg")
    for axis in axes:
        axis.grid(True, alpha=0.3)
        axis.legend()
    fig.suptitle(f"{len(rows)} seeded cases: the paper's rule, the model-based mode and the "
                 'servo (in-process twin)')
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
