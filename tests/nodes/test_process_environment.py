"""What a graph's processes and `omni-micro` itself run with: numpy's OpenBLAS on one thread
unless the user said otherwise (omni_micro_bringup.processes.SINGLE_THREADED_BLAS), and the
OpenBLAS of the lock's numpy and scipy honouring it."""

import os
import re
import subprocess
import sys

import pytest

from omni_micro_bringup.processes import node_environment
from omni_micro_cli.cli import main


def threads_once_numpy_and_scipy_are_imported(env: dict[str, str]) -> int:
    status = subprocess.run(
        [sys.executable, '-c', 'import numpy, scipy.linalg; '
                               "print(open('/proc/self/status').read())"],
        env=env, capture_output=True, text=True, check=True, timeout=60).stdout
    found = re.search(r'^Threads:\s+(\d+)$', status, re.MULTILINE)
    assert found, status
    return int(found.group(1))


@pytest.fixture
def no_blas_setting(monkeypatch):
    """The user set nothing (and whatever the test sets is undone afterwards)."""
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', 'unset below')
    monkeypatch.delenv('OPENBLAS_NUM_THREADS')


def test_a_graphs_processes_import_numpy_and_scipy_without_a_thread_of_their_own(
        no_blas_setting, tmp_path):
    env = node_environment(7, tmp_path)
    assert env['OPENBLAS_NUM_THREADS'] == '1'
    assert threads_once_numpy_and_scipy_are_imported(env) == 1


def test_a_users_own_blas_setting_is_kept(monkeypatch, tmp_path):
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', '3')
    assert node_environment(7, tmp_path)['OPENBLAS_NUM_THREADS'] == '3'
    with pytest.raises(SystemExit):
        main(['simulate', '--help'])
    assert os.environ['OPENBLAS_NUM_THREADS'] == '3'


def test_omni_micro_sets_it_for_itself_before_a_command_loads(no_blas_setting, capsys):
    with pytest.raises(SystemExit):
        main(['simulate', '--help'])
    assert os.environ['OPENBLAS_NUM_THREADS'] == '1'
    assert 'usage: omni-micro simulate' in capsys.readouterr().out
