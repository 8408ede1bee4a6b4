"""The model-based mode: shooting through the slip core, identification of the offsets, the
fall-back to the paper's rule, and what it buys over the paper's rule in the twin."""

import math
import re

import numpy as np
import pytest

from omni_micro_common.conventions import CaptureUncertainty
from omni_micro_control.chains import Chain, RecordedMove, Stop
from omni_micro_control.errors import ControllerConfigError, IdentificationError
from omni_micro_control.feedback import Outcome
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_control.identification import fit_parameters
from omni_micro_control.model_based import ModelBasedPlanner, ModelConfig
from omni_micro_control.observations import Observation
from omni_micro_sim.open_loop import simulate_open_loop
from omni_micro_sim.parameters import RobotParameters
from omni_micro_sim.profile import move_profile
from omni_micro_sim.state import RobotState
from omni_micro_studies.twin import run_closed_loop

MICRO = CaptureUncertainty(0.115e-6, 0.144e-6, 6e-5)
MACRO = CaptureUncertainty(8.6e-6, 10.8e-6, 4.3e-3)


def robot_with(xi2_deg: float, xi3_deg: float, **changes) -> RobotParameters:
    return RobotParameters(wheel_offsets_rad=(0.0, math.radians(xi2_deg),
                                              math.radians(xi3_deg)), **changes)


def test_a_plan_with_the_true_robot_stops_on_the_goal():
    robot = robot_with(3.0, 2.0)
    planner = ModelBasedPlanner(robot)
    start = Observation(0.0, 0.001, -0.002, 0.4, 'macro', CaptureUncertainty(1e-9, 1e-9, 1e-9))
    planner.on_stop(start)
    goal = (0.06, 0.025)
    plan = planner.plan(start, goal, FeedbackConfig(mode='model'))
    assert plan.rule == 'model' and 'shot in' in plan.note
    stop = simulate_open_loop(robot, plan.steering_rad, plan.duration_s,
                              start=RobotState(0.001, -0.002, 0.4)).final_state
    # The slip drifts this 65 mm move by millimetres; the shot aims through it.
    assert math.hypot(stop.x_m - goal[0], stop.y_m - goal[1]) < 1e-9
    # Its planning time is logged (the status reports it); how fast it plans is a figure
    # compare-controllers prints, not a test's bound: it took 4.5 s with the cores kept busy.
    assert len(planner.log.plan_wall_s) == 1 and planner.log.plan_wall_s[0] > 0.0


def chain_of(robot: RobotParameters, moves: list[tuple[float, float]],
             sigmas: list[CaptureUncertainty], seed: int) -> Chain:
    """Stops where ``robot`` really ends each move, seen with the given spreads."""
    rng = np.random.default_rng(seed)
    state = RobotState(0.0, 0.0, 0.2)
    stops, recorded = [], []
    for index, sigma in enumerate(sigmas):
        noise = rng.normal(0.0, 1.0, 3) * [sigma.x_sigma_m, sigma.y_sigma_m,
                                           sigma.heading_sigma_rad]
        stops.append(Stop(state.x_m + noise[0], state.y_m + noise[1], state.phi_rad + noise[2],
                          sigma))
        if index < len(moves):
            steering, duration = moves[index]
            recorded.append(RecordedMove(steering, move_profile(duration)))
            state = simulate_open_loop(robot, steering, duration, start=state).final_state
    return Chain(stops, recorded)


@pytest.mark.parametrize('seed', [0, 1, 2])
def test_identification_recovers_the_offsets_with_intervals_that_hold_the_truth(seed):
    truth = robot_with(-3.7, 2.4)
    # A long move seen by the macro camera, a correction ending under the micro camera.
    chain = chain_of(truth, [(0.1, 6.0), (2.0, 0.7)], [MACRO, MACRO, MICRO], seed)
    fit = fit_parameters([chain], RobotParameters(), ('xi2', 'xi3'))
    errors = np.degrees(fit.values - [math.radians(-3.7), math.radians(2.4)])
    assert np.all(np.abs(errors) < 0.1)
    assert np.all(np.abs(errors) <= np.degrees(fit.half_widths_95))
    assert fit.unidentifiable() == []
    assert fit.reduced_chi_square < 5.0


def test_too_little_motion_leaves_the_offsets_unidentifiable():
    chain = chain_of(robot_with(2.0, -1.0), [(0.5, 1e-4)], [MICRO, MICRO], seed=0)
    fit = fit_parameters([chain], RobotParameters(), ('xi2', 'xi3'))
    assert fit.unidentifiable() == ['xi2', 'xi3']


def test_a_fit_that_wanders_where_moves_never_settle_is_not_identifiable(monkeypatch):
    """Two short moves of a bench run: the fit stepped to offsets under which a move never
    came to rest, and identify ended on that (exit 1, naming the simulation) instead of saying
    that the bag pins nothing down."""
    from omni_micro_control import identification
    from omni_micro_sim.errors import SimulationError

    def wanders(chains, base, names, **_):
        raise SimulationError('the move did not come to rest within 1.0 s of its end')

    monkeypatch.setattr(identification, 'fit_parameters', wanders)
    chain = chain_of(robot_with(2.0, -1.0), [(0.5, 0.05)], [MICRO, MICRO], seed=0)
    with pytest.raises(IdentificationError) as error:
        identification.identify([chain], ('xi2', 'xi3', 'mu_longitudinal'), RobotParameters())
    assert str(error.value) == (
        'not identifiable from this bag, too little motion to pin down: xi2 (its 95 % interval '
        'would be unbounded), xi3 (its 95 % interval would be unbounded), mu_L (its 95 % '
        'interval would be unbounded)')


@pytest.mark.parametrize('chains, names, message', [
    ([Chain([Stop(0.0, 0.0, 0.0, MICRO)], [])], ('xi2',), 'no move between two stops'),
    ([], ('xi2', 'mu'), "cannot fit ['mu']"),
])
def test_a_fit_that_cannot_be_made_says_why(chains, names, message):
    with pytest.raises(IdentificationError, match=re.escape(message)):
        fit_parameters(chains, RobotParameters(), names)


def test_bad_model_settings_are_refused_naming_the_value():
    with pytest.raises(ControllerConfigError, match="got \\['xi9'\\]"):
        ModelConfig(free_parameters=('xi9',))
    with pytest.raises(ControllerConfigError, match='prior_sigma_rad'):
        ModelConfig(prior_sigma_rad=-1.0)


@pytest.mark.parametrize('xi_deg, seed', [((3.0, 2.0), 0), ((-4.7, -1.2), 1), ((5.0, -5.0), 2)])
def test_the_twin_in_model_mode_reaches_in_three_periods_and_learns_the_offsets(xi_deg, seed):
    robot = robot_with(*xi_deg)
    tolerance = FeedbackConfig(tolerance_m=0.5e-6)
    paper = run_closed_loop((0.1, 0.0), robot=robot, seed=seed, config=tolerance)
    model = run_closed_loop((0.1, 0.0), robot=robot, seed=seed,
                            config=FeedbackConfig(mode='model', tolerance_m=0.5e-6))
    assert model.outcome is Outcome.REACHED and paper.outcome is Outcome.REACHED
    assert model.periods <= 3 < paper.periods
    assert model.deviation_m <= 0.5e-6
    assert [move.rule for move in model.moves] == ['model'] * model.periods
    # After the second move, the first to end under the micro camera.
    assert isinstance(model.planner, ModelBasedPlanner)
    learnt = model.planner.log.estimates[1]
    assert math.degrees(learnt['xi2']) == pytest.approx(xi_deg[0], abs=0.1)
    assert math.degrees(learnt['xi3']) == pytest.approx(xi_deg[1], abs=0.1)


def test_a_wrong_model_falls_back_to_the_paper_rule_and_still_reaches():
    # The model assumes wheel 1 is driven; this robot's rolls freely: no offsets explain that.
    robot = robot_with(2.9, 1.7, wheel1_active=False)
    result = run_closed_loop((0.1, 0.0), robot=robot, seed=2,
                             config=FeedbackConfig(mode='model', tolerance_m=0.5e-6))
    assert result.outcome is Outcome.REACHED and result.deviation_m <= 0.5e-6
    fallbacks = [move for move in result.moves if move.rule == 'paper']
    assert fallbacks and all("the paper's rule for this period" in m.note for m in fallbacks)
    assert isinstance(result.planner, ModelBasedPlanner)
    assert "from the model's prediction" in result.planner.log.fallbacks[0]


def test_the_play_operator_puts_the_wheels_where_the_robot_has_them():
    from omni_micro_control.chains import SteeringTracker, wheels_after
    from omni_micro_sim.parameters import steering_preset
    from omni_micro_sim.simulator import STANDING, SlipSimulator

    steering = steering_preset('realistic').replace(backlash_rad=math.radians(3.0))
    simulator = SlipSimulator(RobotParameters(steering=steering))
    tracker = SteeringTracker(steering)
    # Forward, a reversal smaller than the play (the wheels stay), a larger one, a repeat.
    for degrees in (40.0, 38.5, 38.5, 30.0, 170.0, -175.0, -175.0, 0.2):
        angle = math.radians(degrees)
        tracker.move(angle, STANDING)
        simulator.command(angle, STANDING)
        simulator.step(2.0)
        assert simulator.steering_rad == pytest.approx(
            wheels_after(tracker.gear_path, steering.backlash_rad), abs=1e-12)


def test_the_model_mode_learns_the_backlash_of_a_realistic_robot_in_the_twin():
    from omni_micro_sim.parameters import steering_preset

    preset = steering_preset('realistic')
    truth = robot_with(-2.0, 3.5, steering=preset.replace(backlash_rad=math.radians(1.7)))
    result = run_closed_loop((0.1, 0.0005), robot=truth, seed=4,
                             config=FeedbackConfig(mode='model', tolerance_m=0.5e-6),
                             model_robot=RobotParameters(steering=preset))
    paper = run_closed_loop((0.1, 0.0005), robot=truth, seed=4,
                            config=FeedbackConfig(tolerance_m=0.5e-6))
    assert result.outcome is Outcome.REACHED and paper.outcome is Outcome.REACHED
    assert result.periods <= 6 < paper.periods
    assert isinstance(result.planner, ModelBasedPlanner)
    estimate = result.planner.estimate()
    assert abs(math.degrees(estimate['backlash']) - 1.7) < 0.3
