"""`omni-micro identify BAG`: the offsets of robots with known offsets, from their bags alone.
(The bags are recorded with the loop in one process: what identify reads is the bag, and the
composed loop records what separate processes do, tests/graph/test_same_bag.py.)"""

import json
import math

import pytest
import yaml

TRUE_OFFSETS_DEG = (0.0, -2.5, 4.0)


@pytest.fixture(scope='module')
def robot_params(tmp_path_factory):
    path = tmp_path_factory.mktemp('robot') / 'robot.yaml'
    offsets = [math.radians(value) for value in TRUE_OFFSETS_DEG]
    path.write_text(yaml.safe_dump(
        {'dynamics_node': {'ros__parameters': {'robot': {'wheel_offsets_rad': offsets}}}}))
    return path


@pytest.fixture(scope='module')
def recorded(tmp_path_factory, robot_params, omni_micro):
    """Bags of the same robot driven by each controller, and one with a single tiny move."""
    folder = tmp_path_factory.mktemp('bags')
    runs = {'paper': ['--goal-mm', '100,0'],
            'model': ['--goal-mm', '100,0', '--controller', 'model'],
            'tiny': ['--goal-mm', '100.3,0.2', '--open-loop', '0.001']}
    for name, args in runs.items():
        done = omni_micro('run', *args, '--rtf', 'max', '--params', str(robot_params),
                          '--record', str(folder / name), '--quiet', '--composed', '--no-markers',
                          '--log-dir', str(folder / 'logs'))
        assert done.returncode == 0, done.stderr[-2000:]
    return folder


@pytest.mark.parametrize('controller', ['paper', 'model'])
def test_the_offsets_come_back_within_a_tenth_of_a_degree(recorded, controller, omni_micro,
                                                          tmp_path):
    params = tmp_path / 'identified.yaml'
    done = omni_micro('identify', str(recorded / controller), '--json',
                      '--write-params', str(params))
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout)   # the JSON alone; the report goes to stderr
    for found, width, truth in zip(result['wheel_offsets_deg'], result['wheel_offsets_ci_deg'],
                                   TRUE_OFFSETS_DEG, strict=True):
        assert abs(found - truth) < 0.1
        assert abs(found - truth) <= width   # the 95 % interval holds the truth
    assert '| xi2 | `robot.wheel_offsets_rad[1]` |' in done.stderr
    assert 'normalised' in done.stderr   # the residual table
    # Every other fitted parameter: a value and interval under its ROS name, or named vague.
    for name in ('robot.mu_longitudinal', 'robot.mu_transverse', 'robot.cantilever_offset_m'):
        assert name in result['not_identifiable'] or (name in result and f'{name}_ci' in result)
    written = yaml.safe_load(params.read_text())
    offsets = written['dynamics_node']['ros__parameters']['robot']['wheel_offsets_rad']
    assert offsets == written['controller_node']['ros__parameters']['model']['robot'][
        'wheel_offsets_rad']
    assert [math.degrees(v) for v in offsets] == pytest.approx(result['wheel_offsets_deg'])


def test_too_little_motion_says_not_identifiable_instead_of_a_number(recorded, omni_micro,
                                                                     tmp_path):
    params = tmp_path / 'identified.yaml'
    done = omni_micro('identify', str(recorded / 'tiny'), '--fit', 'xi2,xi3', '--json',
                      '--write-params', str(params))
    assert done.returncode == 1
    assert 'not identifiable' in done.stderr and 'xi2' in done.stderr
    assert not params.exists()
    assert '-2.5' not in done.stdout + done.stderr   # no number for what is not identified


TRUE_BACKLASH_DEG = 1.5


def test_a_known_backlash_comes_back_within_its_interval(tmp_path_factory, omni_micro, tmp_path):
    robot = tmp_path_factory.mktemp('backlash') / 'robot.yaml'
    robot.write_text(yaml.safe_dump({'dynamics_node': {'ros__parameters': {'robot': {
        'wheel_offsets_rad': [math.radians(value) for value in TRUE_OFFSETS_DEG],
        'steering': {'backlash_rad': math.radians(TRUE_BACKLASH_DEG)}}}}}))
    bag = tmp_path / 'bag'
    done = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--steering', 'realistic',
                      '--params', str(robot), '--record', str(bag), '--quiet', '--no-markers',
                      '--composed', '--log-dir', str(tmp_path / 'logs'))
    assert done.returncode == 0, done.stderr[-2000:]
    params = tmp_path / 'identified.yaml'
    done = omni_micro('identify', str(bag), '--steering', 'realistic', '--fit',
                      'xi2,xi3,backlash', '--json', '--write-params', str(params))
    assert done.returncode == 0, done.stderr[-2000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    error = result['steering_backlash_deg'] - TRUE_BACKLASH_DEG
    assert abs(error) <= result['steering_backlash_ci_deg'] < 0.3
    for found, width, truth in zip(result['wheel_offsets_deg'], result['wheel_offsets_ci_deg'],
                                   TRUE_OFFSETS_DEG, strict=True):
        assert abs(found - truth) <= max(width, 1e-12)
    written = yaml.safe_load(params.read_text())['dynamics_node']['ros__parameters']['robot']
    assert math.degrees(written['steering']['backlash_rad']) == pytest.approx(
        result['steering_backlash_deg'])
    # The same bag read as if the steering were the paper's: the model cannot explain it.
    ideal = omni_micro('identify', str(bag), '--fit', 'xi2,xi3', '--json')
    assert json.loads(ideal.stdout.strip().splitlines()[-1])['reduced_chi_square'] > 2 * \
        result['reduced_chi_square']


@pytest.mark.parametrize('args, message', [
    (['no/such/bag'], 'does not exist'),
    (['BAG', '--fit', 'xi2,mu'], "expected a comma-separated list of xi2"),
    (['BAG', '--fit', 'xi2,backlash'], 'give --steering realistic'),
])
def test_bad_identify_arguments_exit_2_naming_the_value(args, message, recorded, omni_micro):
    args = [str(recorded / 'paper') if arg == 'BAG' else arg for arg in args]
    done = omni_micro('identify', *args)
    assert done.returncode == 2
    assert message in done.stderr
