"""Each package's package.xml names exactly what its code imports, so that `rosdep install
--from-paths src` on a stock Jazzy machine installs enough (and `colcon` orders the builds)."""

from __future__ import annotations

import ast
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src'
PACKAGES = sorted(path.parent.name for path in SRC.glob('*/package.xml'))
# Python distributions by their rosdep key: the system package where rosdep has one, else the
# `-pip` key (pip-only libraries). An import missing here fails the test: add its key.
ROSDEP_KEYS = {
    'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'numba': 'python3-numba',
    'yaml': 'python3-yaml', 'cv2': 'python3-opencv', 'matplotlib': 'python3-matplotlib',
    'tqdm': 'python3-tqdm', 'pyarrow': 'python3-pyarrow-pip', 'dask': 'python3-dask-pip',
    'distributed': 'python3-distributed-pip', 'rosbags': 'python3-rosbags-pip',
    'mcap': 'python3-mcap-pip', 'mcap_ros2': 'python3-mcap-ros2-support-pip',
    'foxglove': 'python3-foxglove-sdk-pip', 'setproctitle': 'python3-setproctitle',
}
# ROS packages import as themselves (rclpy, geometry_msgs, ...), as do the siblings.
ROS_PACKAGES = {'rclpy', 'builtin_interfaces', 'diagnostic_msgs', 'geometry_msgs', 'nav_msgs',
                'rcl_interfaces', 'rosgraph_msgs', 'sensor_msgs', 'std_msgs', 'std_srvs',
                'trajectory_msgs', 'visualization_msgs', *PACKAGES}


# A bringup package depends on the packages whose nodes it starts, imported or not (as
# nav2_bringup exec_depends on the nav2 servers).
RUNS_NODES_OF = {'omni_micro_bringup': {'omni_micro_sim', 'omni_micro_vision',
                                        'omni_micro_control', 'omni_micro_tools',
                                        'omni_micro_common'}}


def imported_top_names(package: str) -> set[str]:
    names: set[str] = set()
    for path in (SRC / package / package).rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                names.update(alias.name.split('.')[0] for alias in node.names)
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names) - {'__future__', package}


def declared(package: str, tags: tuple[str, ...] = ('exec_depend', 'depend')) -> set[str]:
    root = ET.parse(SRC / package / 'package.xml').getroot()
    return {element.text.strip() for tag in tags for element in root.iter(tag) if element.text}


def test_every_package_is_checked():
    assert {'omni_micro_common', 'omni_micro_sim', 'omni_micro_vision', 'omni_micro_control',
            'omni_micro_tools', 'omni_micro_bringup', 'omni_micro_cli'} <= set(PACKAGES)


@pytest.mark.parametrize('package', PACKAGES)
def test_package_xml_declares_what_the_code_imports(package):
    names = imported_top_names(package)
    unknown = sorted(names - ROS_PACKAGES - set(ROSDEP_KEYS))
    assert not unknown, f'{package} imports {unknown}: add their rosdep keys to ROSDEP_KEYS'
    needed = {ROSDEP_KEYS.get(name, name) for name in names} | RUNS_NODES_OF.get(package, set())
    have = declared(package)
    assert not needed - have, f'{package}/package.xml lacks {sorted(needed - have)}'
    assert not have - needed, f'{package}/package.xml declares unused {sorted(have - needed)}'


@pytest.mark.parametrize('package', PACKAGES)
def test_setup_py_installs_what_package_xml_names(package):
    """The package name, its resource marker and its config files agree (colcon reads both)."""
    root = ET.parse(SRC / package / 'package.xml').getroot()
    assert root.findtext('name') == package
    assert root.findtext('export/build_type') == 'ament_python'
    assert (SRC / package / 'resource' / package).is_file()
    assert f"package_name = '{package}'" in (SRC / package / 'setup.py').read_text()
