"""`colcon build` of the workspace installs the nodes and the omni-micro command where `ros2 run`
looks for them, and the loop closes (recorded) with those executables and the bringup's installed
params file, started by the colcon-installed command."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
NODES = {'omni_micro_sim': 'dynamics_node', 'omni_micro_vision': 'vision_node',
         'omni_micro_control': 'controller_node', 'omni_micro_tools': 'bag_recorder'}
COMMAND = ('omni_micro_cli', 'omni-micro')


@pytest.fixture(scope='module')
def workspace(tmp_path_factory):
    workspace = tmp_path_factory.mktemp('ws')
    shutil.copytree(ROOT / 'ros2_ws' / 'src', workspace / 'src')
    colcon = Path(sys.prefix) / 'bin' / 'colcon'
    build = subprocess.run([str(colcon), 'build'], cwd=workspace, capture_output=True,
                           text=True, timeout=300)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    return workspace


def sourced_environment(workspace: Path) -> dict[str, str]:
    """The environment after `source install/setup.bash`, as on a stock Jazzy machine."""
    dump = subprocess.run(['bash', '-c', 'source install/setup.bash && env -0'],
                          cwd=workspace, capture_output=True, check=True)
    pairs = (item.split('=', 1) for item in dump.stdout.decode().split('\0') if '=' in item)
    return dict(pairs)


def test_executables_and_params_are_where_ros2_run_looks(workspace):
    for package, node in NODES.items():
        executable = workspace / 'install' / package / 'lib' / package / node
        assert executable.is_file() and os.access(executable, os.X_OK)
        assert (workspace / 'install' / package / 'share' / 'ament_index' / 'resource_index' /
                'packages' / package).is_file()
    package, command = COMMAND
    executable = workspace / 'install' / package / 'lib' / package / command
    assert executable.is_file() and os.access(executable, os.X_OK)
    assert (workspace / 'install' / 'omni_micro_bringup' / 'share' / 'omni_micro_bringup' /
            'config' / 'omni_micro.yaml').is_file()


def test_the_loop_closes_with_the_colcon_installed_nodes(workspace, tmp_path):
    env = sourced_environment(workspace)
    where = subprocess.run([sys.executable, '-c', 'import omni_micro_vision; '
                            'print(omni_micro_vision.__file__)'], env=env, capture_output=True,
                           text=True, check=True)
    assert str(workspace / 'install') in where.stdout
    package, command = COMMAND
    omni_micro = workspace / 'install' / package / 'lib' / package / command
    run = subprocess.run([str(omni_micro), 'run', '--goal-mm', '100,0', '--rtf', '5', '--json',
                          '--quiet', '--log-dir', str(tmp_path), '--record',
                          str(tmp_path / 'bag')],
                         env=env, capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-3000:]
    summary = json.loads(run.stdout.strip().splitlines()[-1])
    assert summary['outcome'] == 'reached'
    assert (tmp_path / 'bag' / 'metadata.yaml').is_file()
    for package, node in NODES.items():
        first_line = (Path(summary['log_dir']) / f'{node}.log').read_text().splitlines()[0]
        installed = workspace / 'install' / package
        assert f'{installed}/lib/{package}/{node} --ros-args --params-file ' \
               f'{workspace}/install/omni_micro_bringup/share/omni_micro_bringup/config/' \
               'omni_micro.yaml' in first_line
