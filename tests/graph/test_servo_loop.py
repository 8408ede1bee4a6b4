"""The servo mode through the graph (`run --controller servo`): Fig. 11's goal reached as the twin
reaches it, with the same plans made while rolling from the same captures in motion, and on the
rendered images through the tracker; the same seed records the same bag at another speed with
both cores kept busy (the lockstep waits for every capture in motion the controller acts on:
docs/control.md, "The servo mode")."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from bag_compare import bag_digest

from omni_micro_bringup.composition import GraphOptions
from omni_micro_bringup.graph import GraphResult, run_graph
from omni_micro_cli.twin import run_servo
from omni_micro_control.servo_config import ServoConfig
from omni_micro_sim import paper

SEED = 3
TOLERANCE_M = 0.5e-6


def servo_run(folder: Path, real_time_factor: float = math.inf,
              vision: str = 'model') -> tuple[Path, GraphResult]:
    bag = folder / 'bag'
    result = run_graph(GraphOptions(
        goal_m=paper.FIG11_GOAL_M, seed=SEED, real_time_factor=real_time_factor, record=bag,
        log_dir=folder / 'logs', vision=vision,
        controller_overrides={'mode': 'servo', 'tolerance_m': TOLERANCE_M}))
    # No command arrives after its start stamp, plans made while rolling included.
    assert 'arrived' not in (result.log_dir / 'dynamics_node.log').read_text()
    return bag, result


@pytest.fixture(scope='module')
def reference(tmp_path_factory) -> tuple[Path, GraphResult]:
    return servo_run(tmp_path_factory.mktemp('servo'))


def test_the_servo_over_the_graph_is_the_twin(reference):
    _, graph = reference
    twin = run_servo(paper.FIG11_GOAL_M, robot=paper.FIG11_OPEN_LOOP.robot(), seed=SEED,
                     config=ServoConfig(tolerance_m=TOLERANCE_M))
    assert graph.outcome == twin.outcome.value == 'reached'
    assert graph.periods == twin.periods == 1 and graph.sim_time_s <= 8.0
    assert graph.final_x_m == pytest.approx(twin.final_state.x_m, abs=1e-9)
    assert graph.final_y_m == pytest.approx(twin.final_state.y_m, abs=1e-9)
    assert graph.deviation_m < TOLERANCE_M
    said = {name: int(graph.status[name]) for name in ('stops', 'replans', 'captures_in_motion')}
    assert said == {'stops': twin.stops, 'replans': twin.replans,
                    'captures_in_motion': twin.captures_in_motion}
    assert said['replans'] > 20


def test_same_seed_same_bag_at_another_speed_with_both_cores_kept_busy(reference, tmp_path,
                                                                        busy_machine):
    with busy_machine():
        bag, result = servo_run(tmp_path, real_time_factor=2.0)
    assert result.sim_time_s == reference[1].sim_time_s
    assert bag_digest(bag) == bag_digest(reference[0])


def test_on_the_rendered_images_the_servo_reaches_and_records_the_same_bag_at_any_speed(
        tmp_path, busy_machine):
    """--vision images: the tracker's captures in motion, one per frame from the finest camera
    that follows the robot, drive the same servo."""
    fast_bag, fast = servo_run(tmp_path / 'fast', vision='images')
    assert fast.outcome == 'reached' and fast.deviation_m < TOLERANCE_M
    assert int(fast.status['replans']) > 20 and fast.sim_time_s < 9.0
    with busy_machine():
        slow_bag, slow = servo_run(tmp_path / 'slow', real_time_factor=2.0, vision='images')
    assert slow.sim_time_s == fast.sim_time_s
    assert bag_digest(slow_bag) == bag_digest(fast_bag)
