"""The whole loop over DDS: three processes reach the Fig. 11 goal, exactly as the in-process
runner does, at any real-time factor, and with a stand-in camera that follows the contract."""

import json
import math
import sys
from pathlib import Path

import pytest
from conftest import SHARED_SEED

from omni_micro_bringup.composition import default_nodes
from omni_micro_bringup.graph import run_graph
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_control.feedback_config import FeedbackConfig
from omni_micro_sim import paper
from omni_micro_sim.parameters import steering_preset
from omni_micro_studies.twin import run_closed_loop

GOAL_MM = (100.0, 0.0)
SEED = SHARED_SEED


@pytest.fixture(scope='module')
def in_process():
    return run_closed_loop(paper.FIG11_GOAL_M, robot=paper.FIG11_OPEN_LOOP.robot(), seed=SEED)


@pytest.fixture(scope='module')
def cli_run(tmp_path_factory, omni_micro):
    """`omni-micro run` at rtf 5, as a user types it."""
    logs = tmp_path_factory.mktemp('logs')
    result = omni_micro('run', '--goal-mm', '100,0', '--rtf', '5', '--seed', str(SEED),
                        '--json', '--quiet', '--log-dir', str(logs))
    assert result.returncode == 0, result.stderr[-3000:]
    return json.loads(result.stdout.strip().splitlines()[-1]), logs


def test_closed_loop_over_the_graph_beats_the_paper(cli_run):
    summary, _ = cli_run
    assert summary['outcome'] == 'reached'
    assert summary['deviation_mm'] < paper.FIG11_PUBLISHED_CLOSED_LOOP_DEVIATION_MM
    assert summary['deviation_mm'] < 0.005   # a few micrometres
    assert 20 < summary['periods'] < 60 and summary['sim_time_s'] > 10
    for key in ('final_x_mm', 'final_y_mm', 'final_phi_deg', 'wall_time_s'):
        assert math.isfinite(summary[key])
    run_dir = Path(summary['log_dir'])
    for node in ('dynamics_node', 'vision_node', 'controller_node'):
        assert 'ready' in (run_dir / f'{node}.log').read_text()


def test_graph_adds_no_error_of_its_own(cli_run, in_process):
    summary, _ = cli_run
    assert summary['periods'] == in_process.periods
    assert summary['final_x_mm'] * 1e-3 == pytest.approx(in_process.final_state.x_m, abs=1e-7)
    assert summary['final_y_mm'] * 1e-3 == pytest.approx(in_process.final_state.y_m, abs=1e-7)


def test_same_seed_same_pose_at_another_real_time_factor(cli_run, fig11_recorded):
    summary, _ = cli_run
    _, fast = fig11_recorded     # the same seed, as fast as the lockstep allows, recorded
    assert fast['outcome'] == 'reached'
    assert fast['real_time_factor'] > 5.0
    # To the last digit: the final pose is the first odometry sample at or after the outcome's
    # capture, not the first one the orchestration happened to read (the robot at rest creeps
    # 1e-14 m a tick).
    assert fast['final_x_mm'] == summary['final_x_mm']
    assert fast['final_y_mm'] == summary['final_y_mm']
    assert fast['periods'] == summary['periods']


def test_a_stand_in_camera_that_follows_the_contract_closes_the_loop(tmp_path):
    script = Path(__file__).with_name('standin_camera.py')
    standin = NodeSpec('tests', 'standin_camera', command=(sys.executable, str(script)))
    nodes = [spec if spec.executable != 'vision_node' else standin for spec in default_nodes()]
    # A driver of bare PoseStamped captures: the controller takes their spread from its params.
    spread = [1e-7, 1e-7, 1e-5]
    fixed: dict[str, object] = {'capture_uncertainty': 'fixed',
                                'fixed_uncertainty.macro': spread,
                                'fixed_uncertainty.micro': spread}
    result = run_graph(GraphOptions(goal_m=(0.03, 0.01), real_time_factor=4.0, nodes=nodes,
                                    log_dir=tmp_path, controller_overrides=fixed))
    assert result.outcome == 'reached', result.reason
    assert result.deviation_m < 5e-6


def test_open_loop_option_makes_a_single_move(tmp_path):
    result = run_graph(GraphOptions(goal_m=(0.02, 0.0), open_loop_s=1.0, real_time_factor=4.0,
                                    log_dir=tmp_path))
    assert result.outcome == 'completed' and result.periods == 1
    # One second at cruise rolls r * 8.7 rad/s * 1 s = 14.355 mm (slightly less with slip).
    assert result.final_x_m == pytest.approx(0.014355, abs=0.5e-3)


@pytest.mark.parametrize('args, message', [
    (['--goal-mm', '100'], 'expected 2 comma-separated'),
    (['--goal-mm', 'nan,0'], 'finite'),
    (['--goal-mm', '1,0', '--rtf', '-2'], 'in [0.001, 10000]'),
    (['--goal-mm', '1,0', '--params', 'no/such/file.yaml'], 'does not exist'),
    (['--goal-mm', '1,0', '--controller', 'servo', '--open-loop', '1'],
     '--open-loop makes one move without feedback and the servo mode corrects every move'),
])
def test_bad_run_arguments_exit_2_naming_the_value(args, message, tmp_path, omni_micro):
    result = omni_micro('run', *args, '--log-dir', str(tmp_path / 'logs'))
    assert result.returncode == 2
    assert message in result.stderr
    assert not (tmp_path / 'logs').exists()


def test_params_file_that_does_not_parse_is_refused(tmp_path, omni_micro):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('controller_node: {ros__parameters: [unclosed\n')
    result = omni_micro('run', '--goal-mm', '1,0', '--params', str(bad),
                        '--log-dir', str(tmp_path / 'logs'))
    assert result.returncode == 2 and 'does not parse' in result.stderr


def test_the_model_mode_over_the_graph_is_the_twin(tmp_path):
    twin = run_closed_loop(paper.FIG11_GOAL_M, robot=paper.FIG11_OPEN_LOOP.robot(), seed=SEED,
                           config=FeedbackConfig(mode='model'))
    graph = run_graph(GraphOptions(goal_m=paper.FIG11_GOAL_M, seed=SEED,
                                   real_time_factor=math.inf, log_dir=tmp_path, composed=True,
                                   markers=False, controller_overrides={'mode': 'model'}))
    assert graph.outcome == 'reached' and graph.periods == twin.periods <= 3
    assert graph.final_x_m == pytest.approx(twin.final_state.x_m, abs=1e-7)
    assert graph.final_y_m == pytest.approx(twin.final_state.y_m, abs=1e-7)
    log = next(tmp_path.glob('*/loop_container.log')).read_text()
    assert 'period 2 (model)' in log and 'xi2 2.9' in log   # the offsets as it learns them


def test_realistic_steering_over_the_graph_is_the_twin(tmp_path, omni_micro):
    robot = paper.FIG11_OPEN_LOOP.robot().replace(steering=steering_preset('realistic'))
    twin = run_closed_loop(paper.FIG11_GOAL_M, robot=robot, seed=SEED)
    result = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--seed', str(SEED),
                        '--steering', 'realistic', '--json', '--quiet', '--no-markers',
                        '--composed', '--log-dir', str(tmp_path))
    assert result.returncode == 0, result.stderr[-3000:]
    graph = json.loads(result.stdout.strip().splitlines()[-1])
    assert graph['periods'] == twin.periods
    assert graph['final_x_mm'] * 1e-3 == pytest.approx(twin.final_state.x_m, abs=1e-7)
    assert graph['final_y_mm'] * 1e-3 == pytest.approx(twin.final_state.y_m, abs=1e-7)
    # The steering time counts in every period: later than the same run with ideal steering.
    ideal = run_closed_loop(paper.FIG11_GOAL_M, robot=paper.FIG11_OPEN_LOOP.robot(), seed=SEED)
    assert graph['sim_time_s'] > ideal.sim_time_s
    assert graph['sim_time_s'] == pytest.approx(twin.sim_time_s, abs=0.03)


def test_the_model_mode_with_realistic_steering_over_the_graph_is_the_twin(tmp_path, omni_micro):
    preset = steering_preset('realistic')
    robot = paper.FIG11_OPEN_LOOP.robot().replace(steering=preset)
    # The controller knows the preset's form, not this robot's offsets: as the graph's does.
    twin = run_closed_loop(paper.FIG11_GOAL_M, robot=robot, seed=SEED,
                           config=FeedbackConfig(mode='model'),
                           model_robot=paper.FIG11_OPEN_LOOP.robot().replace(
                               wheel_offsets_rad=(0.0, 0.0, 0.0), steering=preset))
    result = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--seed', str(SEED),
                        '--steering', 'realistic', '--controller', 'model', '--json', '--quiet',
                        '--no-markers', '--composed', '--log-dir', str(tmp_path))
    assert result.returncode == 0, result.stderr[-3000:]
    graph = json.loads(result.stdout.strip().splitlines()[-1])
    assert graph['periods'] == twin.periods <= 6
    assert graph['final_x_mm'] * 1e-3 == pytest.approx(twin.final_state.x_m, abs=1e-7)
    assert graph['final_y_mm'] * 1e-3 == pytest.approx(twin.final_state.y_m, abs=1e-7)
    log = next(tmp_path.glob('*/loop_container.log')).read_text()
    assert 'backlash' in log   # it learns the backlash as it goes


@pytest.mark.parametrize('goal_mm, outcome, exit_code, words', [
    # Outside the micro field only the macro camera sees the goal: it cannot tell 3 um.
    ('50,20', 'unresolved', 1, ('macro', '95 % uncertainty', 'coarser than the 3.00 um')),
    ('100.4,-0.3', 'reached', 0, ('micro', 'at 95 %')),
])
def test_an_outcome_never_claims_more_than_the_camera_sees(goal_mm, outcome, exit_code, words,
                                                           tmp_path, omni_micro):
    result = omni_micro('run', '--goal-mm', goal_mm, '--rtf', 'max', '--json', '--quiet',
                        '--composed', '--no-markers', '--log-dir', str(tmp_path))
    assert result.returncode == exit_code, result.stderr[-2000:]
    summary = json.loads(result.stdout.strip().splitlines()[-1])
    assert summary['outcome'] == outcome
    assert all(word in summary['reason'] for word in words), summary['reason']
    if outcome == 'reached':
        assert summary['deviation_mm'] * 1e3 <= 3.0
