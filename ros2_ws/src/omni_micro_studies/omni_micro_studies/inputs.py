"""What a study can vary and what its runs report: every input of a run with its default, unit
and accepted range, and the metrics of each scenario. Each default is the value of the code that
owns the number (the robot, the cameras, the controller, the paper's Fig. 11), in the user's
units."""

from __future__ import annotations

import math
from dataclasses import dataclass

from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_sim import paper
from omni_micro_sim.parameters import STEERING_PRESETS, RobotParameters
from omni_micro_vision.camera import DEFAULT_RIG, CaptureRule
from omni_micro_vision.motion_capture import CameraTiming

SCENARIOS = ('closed_loop', 'open_loop')
MODES = ('paper', 'model', 'servo')
CLOSED_LOOP = 'closed_loop'


@dataclass(frozen=True)
class Parameter:
    """One input of a run, in the user's units (mm, um, deg, s)."""

    default: float
    unit: str
    help: str
    minimum: float
    maximum: float
    scenarios: tuple[str, ...] = SCENARIOS
    whole: bool = False


# Each default is the value of the dataclass that owns the number (the robot, the cameras, the
# controller, the paper's Fig. 11), in the user's units: one definition of each.
_ROBOT = RobotParameters()
_FEEDBACK = FeedbackConfig()
_MACRO, _MICRO = DEFAULT_RIG.macro, DEFAULT_RIG.micro
_REALISTIC = STEERING_PRESETS['realistic']
_TIMING = CameraTiming()
_MM, _UM = 1e3, 1e6

# The inputs a study can fix, sweep or draw. Ranges are the ones the physics, camera and
# controller models accept (a run outside them would fail, not answer).
PARAMETERS: dict[str, Parameter] = {
    # the robot (section 3)
    **{f'xi{k + 1}_deg': Parameter(math.degrees(_ROBOT.wheel_offsets_rad[k]), 'deg',
                                   f'assembly offset of wheel {k + 1}', -45.0, 45.0)
       for k in range(3)},
    'mu_longitudinal': Parameter(_ROBOT.mu_longitudinal, '',
                                 'friction coefficient along the wheels', 0.0, 2.0),
    'mu_transverse': Parameter(_ROBOT.mu_transverse, '', 'friction coefficient across the wheels',
                               0.0, 2.0),
    'cantilever_offset_mm': Parameter(_ROBOT.cantilever_offset_m * _MM, 'mm',
                                      "wheel 1's cantilever offset d1", 0.0, 5.0),
    'mass_g': Parameter(_ROBOT.mass_kg * 1e3, 'g', "the robot's mass", 0.1, 100.0),
    # the steering motion (with ``steering: realistic`` only; docs/model.md)
    'backlash_deg': Parameter(math.degrees(_REALISTIC.backlash_rad), 'deg',
                              "the steering gears' backlash (realistic steering)", 0.0, 45.0),
    'contact_radius_um': Parameter(_REALISTIC.contact_radius_m * _UM, 'um',
                                   "the wheels' contact radius: pivot friction (realistic "
                                   'steering)', 0.0, 1000.0),
    'steering_rate_deg_s': Parameter(math.degrees(_REALISTIC.rate_rad_s), 'deg/s',
                                     'the wheels\' steering speed limit (realistic steering)',
                                     1.0, 36000.0),
    # the move
    'start_x_mm': Parameter(0.0, 'mm', 'start position x', -1000.0, 1000.0),
    'start_y_mm': Parameter(0.0, 'mm', 'start position y', -1000.0, 1000.0),
    'start_heading_deg': Parameter(0.0, 'deg', 'start heading', -360.0, 360.0),
    'goal_x_mm': Parameter(paper.FIG11_GOAL_M[0] * _MM, 'mm',
                           'goal x (open loop: where the move aims)', -1000.0, 1000.0),
    'goal_y_mm': Parameter(paper.FIG11_GOAL_M[1] * _MM, 'mm', 'goal y', -1000.0, 1000.0),
    # the cameras (closed loop)
    'macro_pixel_um': Parameter(_MACRO.pixel_size_m[0] * _UM, 'um',
                                "macro camera's pixel along x (15 cm field)", 1.0, 5000.0,
                                (CLOSED_LOOP,)),
    'micro_pixel_um': Parameter(_MICRO.pixel_size_m[0] * _UM, 'um',
                                "micro camera's pixel along x (2 mm field)", 0.05, 200.0,
                                (CLOSED_LOOP,)),
    'macro_noise_px': Parameter(_MACRO.noise_px, 'px', "macro tracker's noise per mark", 0.0,
                                20.0, (CLOSED_LOOP,)),
    'micro_noise_px': Parameter(_MICRO.noise_px, 'px', "micro tracker's noise per mark", 0.0,
                                20.0, (CLOSED_LOOP,)),
    # when the cameras capture (closed loop): the frame rate of every capture; exposure, delay
    # and jitter of the captures in motion, which only the servo uses
    'frame_rate_hz': Parameter(CaptureRule.frame_rate_hz, 'Hz', "both cameras' frame rate",
                               1.0, 1000.0, (CLOSED_LOOP,)),
    'exposure_ms': Parameter(_TIMING.exposure_s * 1e3, 'ms', 'exposure of a capture in motion '
                             '(servo)', 0.0, 1000.0, (CLOSED_LOOP,)),
    'latency_ms': Parameter(_TIMING.delay_s * 1e3, 'ms', 'from the end of an exposure to its '
                            'capture reaching the controller (servo)', 0.0, 10_000.0,
                            (CLOSED_LOOP,)),
    'jitter_ms': Parameter(_TIMING.jitter_s * 1e3, 'ms', 'up to this much more latency, drawn '
                           'per frame (servo)', 0.0, 10_000.0, (CLOSED_LOOP,)),
    # the controller (section 4.1, closed loop)
    'timer1_far_s': Parameter(_FEEDBACK.far_period_s, 's', 'timer1 beyond the comparator '
                              'distance', 0.005, 10.0, (CLOSED_LOOP,)),
    'timer1_near_s': Parameter(_FEEDBACK.near_period_s, 's', 'timer1 within the comparator '
                               'distance', 0.005, 10.0, (CLOSED_LOOP,)),
    'timer2_s': Parameter(_FEEDBACK.settle_wait_s, 's', 'timer2: settling wait after each stop',
                          0.0, 10.0, (CLOSED_LOOP,)),
    'comparator_mm': Parameter(_FEEDBACK.comparator_distance_m * _MM, 'mm',
                               "the distance comparator's threshold", 0.001, 1000.0,
                               (CLOSED_LOOP,)),
    'tolerance_um': Parameter(_FEEDBACK.tolerance_m * _UM, 'um', 'the goal tolerance', 0.01, 1e6,
                              (CLOSED_LOOP,)),
    'max_periods': Parameter(_FEEDBACK.max_periods, '', 'periods before giving up', 1, 10_000,
                             (CLOSED_LOOP,), whole=True),
    # The field's own default (0: the mode's own), not an instance's resolved count.
    'captures_per_stop': Parameter(FeedbackConfig.__dataclass_fields__['captures_per_stop']
                                   .default, '',  # type: ignore[arg-type]
                                   "captures averaged per stop (0: the mode's own)", 0, 100,
                                   (CLOSED_LOOP,), whole=True),
}

# What a run can report, per scenario; each name expands to the columns in brackets.
METRICS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    'outcome': (('outcome',), (CLOSED_LOOP,)),
    'deviation_um': (('deviation_um',), (CLOSED_LOOP,)),
    'periods': (('periods',), (CLOSED_LOOP,)),
    'drift_um': (('drift_um',), ('open_loop',)),
    'sim_time_s': (('sim_time_s',), SCENARIOS),
    'final_pose': (('final_x_mm', 'final_y_mm', 'final_heading_deg'), SCENARIOS),
    'identified': (('xi2_identified_deg', 'xi3_identified_deg', 'backlash_identified_deg'),
                   (CLOSED_LOOP,)),
}
# Closed-loop rows always carry these: the minimum a study of the loop is read by.
REQUIRED_METRICS = {CLOSED_LOOP: ('outcome', 'deviation_um', 'periods'),
                    'open_loop': ('drift_um',)}

# The parameters of the steering motion: only a study with ``steering: realistic`` varies them.
STEERING_MOTION_PARAMETERS = ('backlash_deg', 'contact_radius_um', 'steering_rate_deg_s')
