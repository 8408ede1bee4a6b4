"""The controller node's parameters, declared and checked: the one place that says which
parameters ``controller_node`` has and what each becomes (the graph's params file lists
them with their defaults).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node

from omni_micro_common.conventions import (
    PLATFORM_CENTER_M,
    PLATFORM_FRAME,
    PLATFORM_SIZE_M,
    CaptureUncertainty,
)
from omni_micro_common.topic_names import CAPTURE_TOPICS, CAPTURE_UNCERTAINTY_SOURCES
from omni_micro_control.errors import ControllerConfigError
from omni_micro_control.feedback import VisionFeedbackController
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.model_based import ModelConfig, planner_for
from omni_micro_control.platform import checked_platform
from omni_micro_control.servo_config import (
    SERVO_MODE,
    SHARED_WITH_SERVO,
    FilterConfig,
    ServoConfig,
)
from omni_micro_control.servo_session import ServoSession
from omni_micro_control.tuning import retune
from omni_micro_sim.errors import ParameterError
from omni_micro_sim.parameters import MotorLimits, RobotParameters, robot_parameter_values

# FeedbackConfig fields that are no parameter of their own: derived (the motors' cruise speed).
DERIVED_CONFIG = ('cruise_speed_rad_s',)
# When a goal counts from: its arrival (the robot's time then), or its stamp (a coordinator
# hands several robots their goals, each stamped with the end it follows; the lockstep holds
# time until they are taken, so the same run follows whatever the load).
GOAL_TIMES = ('arrival', 'stamp')


@dataclass(frozen=True)
class ControllerParameters:
    limits: MotorLimits
    config: FeedbackConfig
    frame_id: str
    platform_center: list[float]
    platform_size: list[float]
    goal: list[float] | None            # [x_m, y_m] to go to from the start, or none
    uncertainty_source: str
    fixed_uncertainty: dict[str, CaptureUncertainty]
    model_robot: RobotParameters
    model_config: ModelConfig
    servo: ServoConfig | None           # in the servo mode: its settings, the shared ones too
    goal_time: str = 'arrival'          # when a goal counts from (GOAL_TIMES)

    def controller(self) -> VisionFeedbackController | ServoSession:
        """What decides in the mode these parameters say."""
        if self.servo is not None:
            return ServoSession(self.servo, self.limits, self.model_robot)
        return VisionFeedbackController(self.config, planner_for(
            self.config, self.model_robot, self.limits, self.model_config))


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
    servo = _declare_servo_config(node, config)
    frame_id = node.declare_parameter('frame_id', PLATFORM_FRAME).value
    platform_center = list(node.declare_parameter('platform.center_m',
                                                  list(PLATFORM_CENTER_M)).value)
    platform_size = list(node.declare_parameter('platform.size_m', list(PLATFORM_SIZE_M)).value)
    checked_platform(platform_center, platform_size)
    goal = list(node.declare_parameter('goal_m', [0.0]).value)
    if len(goal) != 2 and goal != [0.0]:
        raise ParameterError(f'goal_m must be [x_m, y_m] (or [0.0] for none), got {goal}')
    goal_time = node.declare_parameter('goal_time', 'arrival').value
    if goal_time not in GOAL_TIMES:
        raise ParameterError(f'goal_time must be one of {list(GOAL_TIMES)}, got {goal_time!r}')
    source, fixed = _declare_uncertainty(node)
    return ControllerParameters(limits, config, frame_id, platform_center, platform_size,
                                goal if len(goal) == 2 else None,
                                source, fixed, _declare_model_robot(node),
                                _declare_model_config(node), servo, goal_time)


def reconfigure(controller: VisionFeedbackController | ServoSession,
                changes: dict[str, object]) -> SetParametersResult:
    """The answer to a parameter change while the node runs, made on ``controller`` if it is
    accepted (:func:`omni_micro_control.tuning.retune`: section 4.1's parameters, checked; the
    servo takes those it shares with the other modes, as a fleet's coordinator sets each goal's
    tolerance, and fixes all of its own)."""
    refused = retune(controller, changes)
    return SetParametersResult(successful=refused is None, reason=refused or '')


def _declare_servo_config(node: Node, shared: FeedbackConfig) -> ServoConfig | None:
    """The servo's own parameters (``servo.``, its filter's ``servo.filter.``) and those it
    shares with the other modes; checked, and returned, in the servo mode only."""
    own = {name: node.declare_parameter(f'servo.{name}', field.default).value
           for name, field in ServoConfig.__dataclass_fields__.items()
           if name not in (*SHARED_WITH_SERVO, 'filter')}
    kept = {name: node.declare_parameter(f'servo.filter.{name}', field.default).value
            for name, field in FilterConfig.__dataclass_fields__.items()}
    if shared.mode != SERVO_MODE:
        return None
    if shared.open_loop_duration_s > 0.0 or shared.open_loop_to_goal:
        raise ControllerConfigError(f'open_loop_duration_s must be 0 and open_loop_to_goal '
                                    f'false in the servo mode (it corrects every move), got '
                                    f'{shared.open_loop_duration_s!r} and '
                                    f'{shared.open_loop_to_goal!r}')
    return ServoConfig(**own, **{name: getattr(shared, name) for name in SHARED_WITH_SERVO},
                       filter=FilterConfig(**kept))


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
