"""`omni-micro compare-controllers`: the three modes on the same seeded cases, table and files."""

import json
import subprocess
import sys

import pytest

# Each test starts omni-micro as a process: the slow tier.
pytestmark = pytest.mark.slow


def test_the_modes_run_the_same_cases_and_the_servo_is_the_quickest(tmp_path):
    out = tmp_path / 'compare'
    done = subprocess.run([sys.executable, '-m', 'omni_micro_cli', 'compare-controllers',
                           '--cases', '2', '--workers', '1', '--out', str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert ("| 2 cases, tolerance 0.5 um, ideal steering | paper's rule | model-based | servo |"
            in done.stdout)
    assert '2/2 cases' in done.stderr
    rows = [json.loads(line) for line in (out / 'cases.jsonl').read_text().splitlines()]
    assert [row['index'] for row in rows] == [0, 1]
    for row in rows:
        assert row['paper_outcome'] == row['model_outcome'] == 'reached'
        assert row['model_periods'] <= 3 < row['paper_periods']
        assert row['model_deviation_um'] <= 0.5
        # Rolling, corrected in motion: one stop at the end, sooner than either.
        assert row['servo_outcome'] == 'reached' and row['servo_deviation_um'] <= 0.5
        assert row['servo_stops'] == row['servo_periods'] == 1
        assert row['servo_sim_time_s'] < min(row['model_sim_time_s'], row['paper_sim_time_s'])
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['model_not_worse_percent'] == 100.0
    assert (out / 'comparison.png').stat().st_size > 10_000
    assert (out / 'comparison.md').read_text().strip() in done.stdout


def test_with_realistic_steering_each_robot_has_its_own_backlash_and_both_modes_reach(tmp_path):
    out = tmp_path / 'compare'
    done = subprocess.run([sys.executable, '-m', 'omni_micro_cli', 'compare-controllers',
                           '--cases', '2', '--workers', '1', '--steering', 'realistic',
                           '--out', str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert '2 cases, tolerance 0.5 um, realistic steering' in done.stdout
    rows = [json.loads(line) for line in (out / 'cases.jsonl').read_text().splitlines()]
    assert len({row['backlash_deg'] for row in rows}) == 2
    for row in rows:
        assert 0.0 <= row['backlash_deg'] <= 2.0
        assert row['paper_outcome'] == row['model_outcome'] == 'reached'
        assert row['model_periods'] <= row['paper_periods']
        assert abs(row['backlash_error_deg_last']) < 0.5   # learnt on the way
        # A steering mechanism lets the servo steer only from rest (docs/control.md): it
        # reaches in more moves than with the paper's steering.
        assert row['servo_outcome'] == 'reached' and row['servo_deviation_um'] <= 0.5
        assert 1 < row['servo_periods'] <= 10
    assert 'backlash error after the last move' in done.stdout


def test_the_cases_run_on_an_existing_dask_scheduler_as_in_this_process(tmp_path):
    """--scheduler: the cases go to that scheduler's workers and come back in case order, the
    rows those a run in this process gives; --workers beside it is refused."""
    from distributed import LocalCluster

    from omni_micro_studies.controller_comparison import make_cases, run_case

    out = tmp_path / 'compare'
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host='127.0.0.1',
                      dashboard_address=None) as cluster:
        done = subprocess.run([sys.executable, '-m', 'omni_micro_cli', 'compare-controllers',
                               '--cases', '2', '--seed', '4', '--out', str(out),
                               '--scheduler', cluster.scheduler_address],
                              capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert f'2 cases on the scheduler {cluster.scheduler_address}' in done.stderr
    rows = [json.loads(line) for line in (out / 'cases.jsonl').read_text().splitlines()]
    expected = [run_case(case, 0.5e-6) for case in make_cases(2, 4)]

    def timeless(row: dict) -> dict:
        return {k: v for k, v in row.items() if 'wall_s' not in k and not k.endswith('_route_m')}

    assert [timeless(row) for row in rows] == [timeless(json.loads(json.dumps(row)))
                                               for row in expected]
    both = subprocess.run([sys.executable, '-m', 'omni_micro_cli', 'compare-controllers',
                           '--workers', '2', '--scheduler', 'tcp://127.0.0.1:9',
                           '--out', str(tmp_path / 'no')], capture_output=True, text=True)
    assert both.returncode == 2
    assert both.stderr.strip().endswith('--workers sizes the local cluster; a --scheduler has '
                                        'its own workers')
