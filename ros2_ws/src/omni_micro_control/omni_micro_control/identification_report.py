"""What ``omni-micro identify`` reports of a fit: the table of estimates and residuals
(markdown), its JSON summary, and the params file that makes the dynamics simulate the
identified robot and the model controller start from it."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import yaml

from omni_micro_control.identification import OFFSETS, PARAMETERS, Fit
from omni_micro_control.recorded_runs import RecordedRun


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
