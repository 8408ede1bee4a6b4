"""The paper's published numbers are the acceptance test of the model and its unstated choices."""

import math

import pytest

from omni_micro_sim import simulate_open_loop
from omni_micro_sim.paper import FIG8, FIG8_PUBLISHED_DRIFT_MM, FIG11_OPEN_LOOP
from omni_micro_sim.profile import move_profile
from omni_micro_sim.reference import solve_ivp_reference


def test_fig8_drift_is_0_4727_mm_to_four_significant_digits():
    result = simulate_open_loop(FIG8.robot(), 0.0, FIG8.duration_s)
    assert round(result.drift_m * 1e3, 4) == FIG8_PUBLISHED_DRIFT_MM
    assert result.ideal_stop_m == pytest.approx((28.71e-3, 0.0))


def test_fig11_open_loop_deviation_is_about_13_mm():
    result = simulate_open_loop(FIG11_OPEN_LOOP.robot(), 0.0, FIG11_OPEN_LOOP.duration_s)
    assert result.drift_m * 1e3 == pytest.approx(13.0, abs=0.1)


@pytest.mark.parametrize('scenario', [FIG8, FIG11_OPEN_LOOP], ids=lambda s: s.name)
def test_rk4_agrees_with_tight_solve_ivp_to_0_1_um(scenario):
    params = scenario.robot()
    ours = simulate_open_loop(params, 0.0, scenario.duration_s)
    reference, _ = solve_ivp_reference(params, 0.0, move_profile(scenario.duration_s),
                                       ours.rest_time_s, method='DOP853', rtol=1e-10,
                                       atol=1e-14)
    assert math.hypot(ours.final_state.x_m - reference.x_m,
                      ours.final_state.y_m - reference.y_m) < 1e-7
