"""`omni-micro compare-controllers`: both modes on the same seeded cases, table and files."""

import json
import subprocess
import sys

import pytest

# Each test starts omni-micro as a process: the slow tier.
pytestmark = pytest.mark.slow


def test_both_modes_run_the_same_cases_and_the_model_needs_fewer_periods(tmp_path):
    out = tmp_path / 'compare'
    done = subprocess.run([sys.executable, '-m', 'omni_micro_cli', 'compare-controllers',
                           '--cases', '2', '--workers', '1', '--out', str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "| 2 cases, tolerance 0.5 um | paper's rule | model-based |" in done.stdout
    assert '2/2 cases' in done.stderr
    rows = [json.loads(line) for line in (out / 'cases.jsonl').read_text().splitlines()]
    assert [row['index'] for row in rows] == [0, 1]
    for row in rows:
        assert row['paper_outcome'] == row['model_outcome'] == 'reached'
        assert row['model_periods'] <= 3 < row['paper_periods']
        assert row['model_deviation_um'] <= 0.5
    summary = json.loads((out / 'summary.json').read_text())
    assert summary['model_not_worse_percent'] == 100.0
    assert (out / 'comparison.png').stat().st_size > 10_000
    assert (out / 'comparison.md').read_text().strip() in done.stdout
