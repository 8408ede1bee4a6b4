"""omni-micro sets numpy's OpenBLAS to one thread for itself before a command loads, as it does
for a graph's processes (tests/nodes/test_process_environment.py), unless the user set it."""

import os

import pytest

from omni_micro_cli.cli import main


def test_a_users_own_blas_setting_is_kept_by_omni_micro(monkeypatch):
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', '3')
    with pytest.raises(SystemExit):
        main(['simulate', '--help'])
    assert os.environ['OPENBLAS_NUM_THREADS'] == '3'


def test_omni_micro_sets_it_for_itself_before_a_command_loads(no_blas_setting, capsys):
    with pytest.raises(SystemExit):
        main(['simulate', '--help'])
    assert os.environ['OPENBLAS_NUM_THREADS'] == '1'
    assert 'usage: omni-micro simulate' in capsys.readouterr().out
