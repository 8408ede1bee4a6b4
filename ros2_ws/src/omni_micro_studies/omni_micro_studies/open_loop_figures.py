"""The paper's open-loop figures from the slip core, with the numbers they show: Figs. 6, 7,
8(a)(b)(c), the open-loop route of Fig. 11 and the realistic steering's turn, written as PNG
files beside figures.json and comparison.md (the paper's numbers beside ours)."""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from omni_micro_sim import paper

TRACE_INTERVAL_S = 1e-3


def _silent(message: str) -> None:
    """No progress said."""


def write_figures(out: Path, angle_step_deg: float, offset_step_deg: float,
                  progress: Callable[[str], None] = _silent) -> dict[str, float]:
    """Each figure into ``out`` as a PNG, with figures.json and comparison.md; Fig. 6 at
    ``angle_step_deg``, Fig. 7 at ``offset_step_deg``. Returns the numbers the figures show
    (figures.json's), and says each step to ``progress``."""
    # Loaded when figures are drawn, not when the command line reads its verbs.
    from omni_micro_sim import RobotParameters, simulate_open_loop, simulate_open_loop_batch
    from omni_micro_studies import paper_figures as plots

    base = RobotParameters()
    numbers: dict[str, float] = {}

    # Fig. 6: drift against direction angle, wheel 1 active or passive.
    angles_deg = np.arange(0.0, 360.0 + 1e-9, angle_step_deg)
    duration6 = paper.duration_for_distance(paper.FIG6_DISTANCE_M)
    progress(f'fig. 6: {2 * angles_deg.size} moves of {paper.FIG6_DISTANCE_M * 1e3:.3f} mm')
    curves6 = {}
    for label, active in (('wheel 1 active', True), ('wheel 1 passive', False)):
        batch = simulate_open_loop_batch(base.replace(wheel1_active=active),
                                         np.radians(angles_deg), duration6)
        curves6[label] = batch.drifts_m
    plots.drift_curves(out / 'fig6_wheel1_state.png', angles_deg, curves6,
                       xlabel='direction angle theta (deg)',
                       title='Fig. 6: drift vs direction angle, 14.355 mm move')
    for label, key in (('wheel 1 active', 'active'), ('wheel 1 passive', 'passive')):
        numbers[f'fig6_{key}_mean_drift_mm'] = float(np.mean(curves6[label]) * 1e3)
        numbers[f'fig6_{key}_max_drift_mm'] = float(np.max(curves6[label]) * 1e3)

    # Fig. 7: drift against the common offset of wheels 2 and 3.
    low, high = paper.FIG7_OFFSET_RANGE_DEG
    offsets_deg = np.linspace(low, high, round((high - low) / offset_step_deg) + 1)
    goal = np.array(paper.FIG7_GOAL_M)
    steering7 = math.atan2(goal[1], goal[0])
    duration7 = paper.duration_for_distance(float(np.hypot(*goal)))
    progress(f'fig. 7: {offsets_deg.size} moves to (10.15, 10.15) mm')
    robots = [base.replace(wheel_offsets_rad=(0.0, math.radians(xi), math.radians(xi)))
              for xi in offsets_deg]
    batch7 = simulate_open_loop_batch(robots, np.full(offsets_deg.size, steering7), duration7)
    plots.drift_curves(out / 'fig7_assembly_error.png', offsets_deg,
                       {'wheels 2 and 3 offset by xi': batch7.drifts_m},
                       xlabel='offset angle xi (deg)',
                       title='Fig. 7: drift vs assembly offset, (0,0) to (10.15,10.15) mm')
    for xi in (low, 0.0, high):
        index = int(np.argmin(np.abs(offsets_deg - xi)))
        numbers[f'fig7_drift_at_{xi:+g}deg_mm'] = float(batch7.drifts_m[index] * 1e3)

    # Fig. 8 and the open-loop route of Fig. 11, with traces.
    for scenario, key in ((paper.FIG8, 'fig8'), (paper.FIG11_OPEN_LOOP, 'fig11')):
        progress(f'{scenario.name}: traced move of {scenario.duration_s:g} s')
        result = simulate_open_loop(scenario.robot(base), math.radians(scenario.steering_deg),
                                    scenario.duration_s, sample_interval_s=TRACE_INTERVAL_S)
        trace = result.trace
        assert trace is not None
        ideal = np.array([[0.0, 0.0], result.ideal_stop_m])
        if key == 'fig8':
            numbers['fig8_drift_mm'] = result.drift_m * 1e3
            numbers['fig8_final_phi_deg'] = math.degrees(result.final_state.phi_rad)
            for name, component, panel in (('slip_longitudinal_m_s', 'longitudinal', 'a'),
                                           ('slip_transverse_m_s', 'transverse', 'b')):
                plots.wheel_slip(out / f'fig8{panel}_{component}_slip.png', trace['time_s'],
                                 trace[name], component=component,
                                 title=f'Fig. 8({panel}): {component} slip velocity')
            plots.routes(out / 'fig8c_route.png', {'simulated route': trace['state'][:, :2]},
                         ideal_m=ideal, goal_m=result.ideal_stop_m,
                         title=f'Fig. 8(c): route, 28.71 mm in 2 s (drift '
                               f'{result.drift_m * 1e3:.4f} mm)')
        else:
            numbers['fig11_open_loop_deviation_mm'] = result.drift_m * 1e3
            plots.routes(out / 'fig11_open_loop_route.png',
                         {'open loop (no feedback)': trace['state'][:, :2]}, ideal_m=ideal,
                         goal_m=result.ideal_stop_m,
                         title=f'Fig. 11: open-loop route, 7 s (deviation '
                               f'{result.drift_m * 1e3:.2f} mm)')

    numbers.update(steering_figure(out, progress))
    (out / 'figures.json').write_text(json.dumps(numbers, indent=2) + '\n')
    (out / 'comparison.md').write_text(comparison_table(numbers))
    return numbers


STEERING_RADII_M = (10e-6, 25e-6, 50e-6, 100e-6, 150e-6)


def steering_figure(out: Path, progress: Callable[[str], None] = _silent) -> dict[str, float]:
    """The chassis heading turned by steering-only moves of the realistic steering (no
    backlash, continuous steps), against the steering angle and the contact radius."""
    from omni_micro_sim import RobotParameters, simulate_open_loop
    from omni_micro_sim.parameters import steering_preset
    from omni_micro_studies import paper_figures as plots

    angles_deg = np.arange(15.0, 180.0 + 1e-9, 15.0)
    progress(f'steering: {angles_deg.size * len(STEERING_RADII_M)} steering-only moves')
    preset = steering_preset('realistic').replace(backlash_rad=0.0, step_rad=0.0)
    base = RobotParameters()
    turns: dict[float, np.ndarray] = {}
    ratios: dict[float, float] = {}
    for radius in STEERING_RADII_M:
        robot = base.replace(steering=preset.replace(contact_radius_m=radius))
        turns[radius] = np.array([
            simulate_open_loop(robot, math.radians(angle), 0.0,
                               steer_from_rad=0.0).final_state.phi_rad for angle in angles_deg])
        pivot = preset.pivot_coefficient * radius ** 2
        ratios[radius] = pivot / (base.wheel_distance_m ** 2 + pivot)
    plots.steering_turn(out / 'steering_turn.png', angles_deg, turns, ratios)
    return {'steering_90deg_turn_mdeg_at_50um': float(
        np.degrees(turns[50e-6][list(angles_deg).index(90.0)]) * 1e3)}


def comparison_table(numbers: dict[str, float]) -> str:

    rows = [
        ('Fig. 8: drift after 28.71 mm in 2 s (xi = 0, 3, 2 deg)',
         f'{paper.FIG8_PUBLISHED_DRIFT_MM} mm', f'{numbers["fig8_drift_mm"]:.4f} mm'),
        ('Fig. 11: open-loop deviation after 7 s toward (100, 0) mm',
         f'about {paper.FIG11_PUBLISHED_OPEN_LOOP_DEVIATION_MM:g} mm',
         f'{numbers["fig11_open_loop_deviation_mm"]:.3f} mm'),
        ('Fig. 6: passive wheel 1 drifts much more than active (mean over theta)',
         'passive >> active',
         f'active {numbers["fig6_active_mean_drift_mm"]:.4f} mm, passive '
         f'{numbers["fig6_passive_mean_drift_mm"]:.4f} mm'),
        ('Fig. 7: drift grows as xi leaves 0',
         'minimum near xi = 0',
         f'{numbers["fig7_drift_at_-10deg_mm"]:.3f} / {numbers["fig7_drift_at_+0deg_mm"]:.4f} / '
         f'{numbers["fig7_drift_at_+10deg_mm"]:.3f} mm at xi = -10 / 0 / +10 deg'),
    ]
    lines = ['# The paper\'s numbers beside omni-micro\'s', '',
             '| result | paper | omni-micro |', '| --- | --- | --- |']
    lines += [f'| {a} | {b} | {c} |' for a, b, c in rows]
    return '\n'.join(lines) + '\n'
