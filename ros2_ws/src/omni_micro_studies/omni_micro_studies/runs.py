"""One run of a study, from its row of inputs alone: the twin for the loop, the core for a move.

Workers call :func:`run_rows`; it only needs importable code and the rows, so a worker on
another machine computes exactly what a local one does.
"""

from __future__ import annotations

import math
import time
from typing import Any

from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.model_based import ModelBasedPlanner
from omni_micro_control.servo_config import ServoConfig
from omni_micro_sim import paper
from omni_micro_sim.open_loop import simulate_open_loop
from omni_micro_sim.parameters import RobotParameters, SteeringParameters, steering_preset
from omni_micro_sim.state import RobotState
from omni_micro_studies.twin import ClosedLoopResult, ServoResult, run_closed_loop, run_servo
from omni_micro_vision.camera import DEFAULT_RIG, CameraModel, CameraRig, CaptureRule
from omni_micro_vision.motion_capture import CameraTiming

# Failed runs are rows too (a study keeps going): their outcome says so, the error says why.
FAILED = 'failed'


def steering_of(row: dict[str, Any]) -> SteeringParameters:
    """The row's steering: its preset, with the row's own values where it steers in time."""
    preset = steering_preset(row.get('steering', 'ideal'))
    if preset.instantaneous:
        return preset
    return preset.replace(
        backlash_rad=math.radians(row['backlash_deg']),
        contact_radius_m=row['contact_radius_um'] / 1e6,
        motor_speed_rad_s=math.radians(row['steering_rate_deg_s']) * preset.gear_ratio)


def robot_of(row: dict[str, Any]) -> RobotParameters:
    return RobotParameters(
        wheel_offsets_rad=(math.radians(row['xi1_deg']), math.radians(row['xi2_deg']),
                           math.radians(row['xi3_deg'])),
        mu_longitudinal=row['mu_longitudinal'], mu_transverse=row['mu_transverse'],
        cantilever_offset_m=row['cantilever_offset_mm'] * 1e-3, mass_kg=row['mass_g'] * 1e-3,
        steering=steering_of(row))


def start_of(row: dict[str, Any]) -> RobotState:
    return RobotState(row['start_x_mm'] * 1e-3, row['start_y_mm'] * 1e-3,
                      math.radians(row['start_heading_deg']))


def _camera(model: CameraModel, pixel_um: float, noise_px: float) -> CameraModel:
    # The sensor keeps its aspect ratio: a finer pixel along x means more pixels both ways.
    columns = max(1, round(model.field_m[0] / (pixel_um * 1e-6)))
    rows = max(1, round(columns * model.resolution_px[1] / model.resolution_px[0]))
    return CameraModel(model.name, model.center_m, model.field_m, (columns, rows), noise_px,
                       model.quantisation_px, model.marker_baseline_m)


def rig_of(row: dict[str, Any]) -> CameraRig:
    return CameraRig(
        macro=_camera(DEFAULT_RIG.macro, row['macro_pixel_um'], row['macro_noise_px']),
        micro=_camera(DEFAULT_RIG.micro, row['micro_pixel_um'], row['micro_noise_px']))


def config_of(row: dict[str, Any]) -> FeedbackConfig:
    return FeedbackConfig(
        settle_wait_s=row['timer2_s'], far_period_s=row['timer1_far_s'],
        near_period_s=row['timer1_near_s'], comparator_distance_m=row['comparator_mm'] * 1e-3,
        tolerance_m=row['tolerance_um'] * 1e-6, max_periods=int(row['max_periods']),
        mode=row['mode'], captures_per_stop=int(row['captures_per_stop']))


def _pose(state: RobotState) -> dict[str, float]:
    return {'final_x_mm': state.x_m * 1e3, 'final_y_mm': state.y_m * 1e3,
            'final_heading_deg': math.degrees(state.phi_rad)}


def timing_of(row: dict[str, Any]) -> CameraTiming:
    return CameraTiming(frame_rate_hz=row['frame_rate_hz'], exposure_s=row['exposure_ms'] * 1e-3,
                        delay_s=row['latency_ms'] * 1e-3, jitter_s=row['jitter_ms'] * 1e-3)


def closed_loop(row: dict[str, Any]) -> dict[str, Any]:
    goal = (row['goal_x_mm'] * 1e-3, row['goal_y_mm'] * 1e-3)
    # The controllers know the steering's form, not this robot's values.
    known = RobotParameters(steering=steering_preset(row.get('steering', 'ideal')))
    rule = CaptureRule(frame_rate_hz=row['frame_rate_hz'])
    result: ClosedLoopResult
    if row['mode'] == 'servo':
        timing = timing_of(row)
        result = run_servo(goal, robot=robot_of(row), rig=rig_of(row),
                           config=ServoConfig(tolerance_m=row['tolerance_um'] * 1e-6,
                                              max_moves=int(row['max_periods'])),
                           timings={'macro': timing, 'micro': timing}, rule=rule,
                           seed=int(row['seed']), start=start_of(row), model_robot=known)
    else:
        result = run_closed_loop(goal, robot=robot_of(row), config=config_of(row),
                                 rig=rig_of(row), rule=rule, seed=int(row['seed']),
                                 start=start_of(row), model_robot=known)
    metrics: dict[str, Any] = {
        'outcome': result.outcome.value, 'deviation_um': result.deviation_m * 1e6,
        'periods': result.periods, 'sim_time_s': result.sim_time_s,
        **_pose(result.final_state)}
    if isinstance(result, ServoResult):
        metrics['xi2_identified_deg'] = math.degrees(result.offsets_rad[0])
        metrics['xi3_identified_deg'] = math.degrees(result.offsets_rad[1])
    if isinstance(result.planner, ModelBasedPlanner) and result.planner.log.estimates:
        last = result.planner.log.estimates[-1]
        metrics['xi2_identified_deg'] = math.degrees(last['xi2'])
        metrics['xi3_identified_deg'] = math.degrees(last['xi3'])
        if 'backlash' in last:
            metrics['backlash_identified_deg'] = math.degrees(last['backlash'])
    return metrics


def open_loop(row: dict[str, Any]) -> dict[str, Any]:
    dx = (row['goal_x_mm'] - row['start_x_mm']) * 1e-3
    dy = (row['goal_y_mm'] - row['start_y_mm']) * 1e-3
    robot = robot_of(row)
    # Steering is in the robot's frame: aim at the goal from the start heading.
    steering = math.atan2(dy, dx) - math.radians(row['start_heading_deg'])
    duration = paper.duration_for_distance(math.hypot(dx, dy), base=robot)
    result = simulate_open_loop(robot, steering, duration, start=start_of(row))
    return {'drift_um': result.drift_m * 1e6, 'sim_time_s': result.rest_time_s,
            **_pose(result.final_state)}


def run_row(row: dict[str, Any], columns: list[str]) -> dict[str, Any]:
    """The row with its metrics (``columns``; absent ones are null), its wall time and error."""
    began = time.perf_counter()
    error = None
    try:
        metrics = closed_loop(row) if row['mode'] != 'open_loop' else open_loop(row)
    except (ValueError, ArithmeticError, RuntimeError) as failure:
        # Every error of the models is one of these (ParameterError, CommandError,
        # SimulationError, ControllerConfigError, CameraConfigError); a study records it.
        metrics = {'outcome': FAILED} if 'outcome' in columns else {}
        error = f'{type(failure).__name__}: {failure}'
    return {**row, **{column: metrics.get(column) for column in columns},
            'wall_s': time.perf_counter() - began, 'error': error}


def warm_up() -> None:
    """Load the numba kernels (from their cache) with one short move, before any timed run."""
    simulate_open_loop(RobotParameters(), 0.0, 0.05)


def run_rows(rows: list[dict[str, Any]], columns: list[str]) -> list[dict[str, Any]]:
    return [run_row(row, columns) for row in rows]
