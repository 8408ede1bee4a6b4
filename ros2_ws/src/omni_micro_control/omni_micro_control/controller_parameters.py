"""The controller node's parameters, declared and checked: the one place that says which
parameters ``controller_node`` has and what each becomes (the graph's params file lists
them with their defaults).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rclpy.node import Node

from omni_micro_common.conventions import PLATFORM_CENTER_M, PLATFORM_SIZE_M, CaptureUncertainty
from omni_micro_common.topic_names import CAPTURE_TOPICS, CAPTURE_UNCERTAINTY_SOURCES
from omni_micro_control.feedback import FeedbackConfig
from omni_micro_control.model_based import ModelConfig
from omni_micro_control.platform import checked_platform
from omni_micro_sim.errors import ParameterError
from omni_micro_sim.parameters import MotorLimits, RobotParameters, robot_parameter_values

# FeedbackConfig fields that are no parameter of their own: derived (the motors' cruise speed).
DERIVED_CONFIG = ('cruise_speed_rad_s',)


@dataclass(frozen=True)
class ControllerParameters:
    limits: MotorLimits
    config: FeedbackConfig
    frame_id: str
    platform_center: list[float]
    platform_size: list[float]
    goal: list[float]
    uncertainty_source: str
    fixed_uncertainty: dict[str, CaptureUncertainty]
    model_robot: RobotParameters
    model_config: ModelConfig


def declare_controller_parameters(node: Node) -> ControllerParameters:
    """Declare every parameter of the controller on ``node`` and check them.

    Raises
    ------
    ParameterError, omni_micro_control.errors.ControllerConfigError
        Naming the parameter and what it must be.
    """
    limits = MotorLimits(**{
        name: node.declare_parameter(f'motor.{name}', getattr(MotorLimits(), name)).value
        for name in MotorLimits.__dataclass_fields__})
    # The fields' own defaults, not a FeedbackConfig()'s: captures_per_stop 0 means "the
    # mode's own", which an instance has already resolved. The cruise speed is the motors'.
    config = FeedbackConfig(cruise_speed_rad_s=limits.cruise_speed_rad_s, **{
        name: node.declare_parameter(name, field.default).value
        for name, field in FeedbackConfig.__dataclass_fields__.items()
        if name not in DERIVED_CONFIG})
    frame_id = node.declare_parameter('frame_id', 'platform').value
    platform_center = list(node.declare_parameter('platform.center_m',
                                                  list(PLATFORM_CENTER_M)).value)
    platform_size = list(node.declare_parameter('platform.size_m', list(PLATFORM_SIZE_M)).value)
    checked_platform(platform_center, platform_size)
    goal = list(node.declare_parameter('goal_m', [0.0]).value)
    source, fixed = _declare_uncertainty(node)
    return ControllerParameters(limits, config, frame_id, platform_center, platform_size, goal,
                                source, fixed, _declare_model_robot(node),
                                _declare_model_config(node))


def _declare_uncertainty(node: Node) -> tuple[str, dict[str, CaptureUncertainty]]:
    source = node.declare_parameter('capture_uncertainty', 'covariance').value
    # The camera's PoseWithCovarianceStamped beside each capture, or (a driver that
    # publishes bare PoseStamped captures) this node's parameters.
    if source not in CAPTURE_UNCERTAINTY_SOURCES:
        raise ParameterError(f'capture_uncertainty must be one of '
                             f'{list(CAPTURE_UNCERTAINTY_SOURCES)}, got {source!r}')
    fixed_uncertainty: dict[str, CaptureUncertainty] = {}
    for name in CAPTURE_TOPICS:
        key = f'fixed_uncertainty.{name}'
        values = list(node.declare_parameter(key, [0.0, 0.0, 0.0]).value)
        if source != 'fixed':
            continue
        if len(values) != 3 or not all(math.isfinite(v) and v > 0.0 for v in values):
            raise ParameterError(
                f'{key} must be [x_sigma_m, y_sigma_m, heading_sigma_rad], three numbers '
                f'> 0 (capture_uncertainty is fixed), got {values}')
        fixed_uncertainty[name] = CaptureUncertainty(*map(float, values))
    return str(source), fixed_uncertainty


def _declare_model_robot(node: Node) -> RobotParameters:
    """The model mode's nominal robot: what it assumes of every parameter it does not
    fit, and where the fitted ones start (no offsets by default)."""
    return RobotParameters.from_mapping({
        name: node.declare_parameter(f'model.robot.{name}', default).value
        for name, default in robot_parameter_values(RobotParameters()).items()})


def _declare_model_config(node: Node) -> ModelConfig:
    defaults = ModelConfig()
    return ModelConfig(
        free_parameters=tuple(node.declare_parameter(
            'model.free_parameters', list(defaults.free_parameters)).value),
        prior_sigma_rad=node.declare_parameter('model.prior_sigma_rad',
                                               defaults.prior_sigma_rad).value,
        max_chain_moves=node.declare_parameter('model.max_chain_moves',
                                               defaults.max_chain_moves).value)
