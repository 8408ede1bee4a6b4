"""What a graph's processes run with: numpy's OpenBLAS on one thread unless the user said
otherwise (omni_micro_bringup.processes.SINGLE_THREADED_BLAS), and the OpenBLAS of the lock's
numpy and scipy honouring it (omni-micro itself: tests/cli/test_blas_threads.py)."""

import re
import subprocess
import sys

from omni_micro_bringup.processes import node_environment


def threads_once_numpy_and_scipy_are_imported(env: dict[str, str]) -> int:
    status = subprocess.run(
        [sys.executable, '-c', 'import numpy, scipy.linalg; '
                               "print(open('/proc/self/status').read())"],
        env=env, capture_output=True, text=True, check=True, timeout=60).stdout
    found = re.search(r'^Threads:\s+(\d+)$', status, re.MULTILINE)
    assert found, status
    return int(found.group(1))


def test_a_graphs_processes_import_numpy_and_scipy_without_a_thread_of_their_own(
        no_blas_setting, tmp_path):
    env = node_environment(7, tmp_path)
    assert env['OPENBLAS_NUM_THREADS'] == '1'
    assert threads_once_numpy_and_scipy_are_imported(env) == 1


def test_a_users_own_blas_setting_is_kept(monkeypatch, tmp_path):
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', '3')
    assert node_environment(7, tmp_path)['OPENBLAS_NUM_THREADS'] == '3'
