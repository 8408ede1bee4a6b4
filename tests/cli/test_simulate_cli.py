"""The open-loop command line, run as a user runs it."""

import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

# Each test starts omni-micro as a process: the slow tier.
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def omni_micro(*args, check=False):
    return subprocess.run([sys.executable, '-m', 'omni_micro_cli', *args], cwd=ROOT,
                          capture_output=True, text=True, check=check)


def test_simulate_json_reports_fig8():
    done = omni_micro('simulate', '--theta-deg', '0', '--duration', '2', '--xi-deg', '0,3,2',
                      '--json', check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result['drift_mm'] == pytest.approx(0.4727, abs=5e-5)
    assert result['x_mm'] == pytest.approx(28.6886, abs=1e-3)
    assert result['phi_deg'] < 0.0
    assert result['passive_wheel1'] is False


def test_passive_wheel1_changes_the_result():
    active = omni_micro('simulate', '--theta-deg', '0', '--duration', '1', '--json', check=True)
    passive = omni_micro('simulate', '--theta-deg', '0', '--duration', '1', '--passive-wheel1',
                         '--json', check=True)
    a = json.loads(active.stdout.splitlines()[-1])
    p = json.loads(passive.stdout.splitlines()[-1])
    assert p['drift_mm'] > 3 * a['drift_mm']


def test_a_steering_only_move_turns_the_chassis_against_the_steering():
    done = omni_micro('simulate', '--theta-deg', '90', '--duration', '0', '--steer-from-deg',
                      '0', '--steering', 'realistic', '--json', check=True)
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result['steering_time_s'] == pytest.approx(0.6, abs=0.01)
    assert result['final_steering_deg'] == pytest.approx(89.5, abs=0.06)   # half the play
    assert -0.01 < result['phi_deg'] < -0.005
    assert math.hypot(result['x_mm'], result['y_mm']) < 1e-9
    ideal = omni_micro('simulate', '--theta-deg', '90', '--duration', '1', '--json', check=True)
    assert json.loads(ideal.stdout.strip().splitlines()[-1])['steering_time_s'] == 0.0


@pytest.mark.parametrize('args, named', [
    (['--theta-deg', '0', '--duration', '0'], '--steer-from-deg'),
    (['--theta-deg', '0', '--duration', '1', '--steering', 'sloppy'], '--steering'),
    (['--theta-deg', '0', '--duration', '1', '--steer-from-deg', 'nan'], '--steer-from-deg'),
    (['--theta-deg', '0', '--duration', 'nan'], '--duration'),
    (['--theta-deg', '0', '--duration', '-1'], '--duration'),
    (['--theta-deg', 'inf', '--duration', '1'], '--theta-deg'),
    (['--theta-deg', '0', '--duration', '1', '--xi-deg', '1,2'], '--xi-deg'),
    (['--theta-deg', '0', '--duration', '1', '--xi-deg', '0,95,0'], 'wheel_offsets_rad'),
])
def test_bad_values_exit_2_and_name_the_value(args, named):
    done = omni_micro('simulate', *args)
    assert done.returncode == 2
    assert named in done.stderr
    assert done.stdout == ''


def test_figures_writes_every_figure_and_the_table(tmp_path):
    out = tmp_path / 'figs'
    omni_micro('figures', '--out', str(out), '--angle-step-deg', '30', '--offset-step-deg', '5',
               check=True)
    names = {p.name for p in out.iterdir()}
    assert {'fig6_wheel1_state.png', 'fig7_assembly_error.png', 'fig8a_longitudinal_slip.png',
            'fig8b_transverse_slip.png', 'fig8c_route.png', 'fig11_open_loop_route.png',
            'steering_turn.png', 'comparison.md', 'figures.json'} <= names
    numbers = json.loads((out / 'figures.json').read_text())
    assert round(numbers['fig8_drift_mm'], 4) == 0.4727
    assert -10 < numbers['steering_90deg_turn_mdeg_at_50um'] < -8
    assert not [p for p in tmp_path.iterdir() if '.partial-' in p.name]


def test_figures_bad_step_writes_nothing(tmp_path):
    out = tmp_path / 'figs'
    done = omni_micro('figures', '--out', str(out), '--angle-step-deg', '0')
    assert done.returncode == 2 and '--angle-step-deg' in done.stderr
    assert not out.exists()


def test_bench_reports_figures_and_agrees_with_its_reference():
    done = omni_micro('bench', '--batch', '10', '--repeats', '2', '--json', check=True)
    figures = json.loads(done.stdout.strip().splitlines()[-1])
    assert figures['final_position_difference_um'] < 0.1
    assert figures['reference_rhs_calls'] > 100
    assert figures['speedup_vs_reference'] > 1.0
    assert figures['batch_moves'] == 10


def test_demo_runs_fig11_through_the_graph(tmp_path):
    """The README's main command, as a newcomer runs it: every row it prints is the README's.
    (What --record adds, a bag per run, is test_demo_records_each_run_into_a_bag_of_its_own.)"""
    done = omni_micro('demo', '--out', str(tmp_path / 'demo'), '--rtf', 'max', check=True)
    assert '| Fig. 8: drift after 28.71 mm in 2 s (xi = 0, 3, 2 deg) | 0.4727 mm | 0.4727 mm |' \
        in done.stdout
    assert '| vision feedback: deviation | 0.0124 mm | 0.00' in done.stdout
    assert (tmp_path / 'demo' / 'fig8c_route.png').stat().st_size > 10_000
    assert (tmp_path / 'demo' / 'fig11_graph_comparison.png').stat().st_size > 10_000
    # The README shows what demo prints, row for row.
    readme = (ROOT / 'README.md').read_text()
    section = readme.split('## What `demo` prints', 1)[1].split('\n## ', 1)[0]
    headers = ('| result', '| Fig. 11, (0,0)', '| ---')
    rows = [line for line in section.splitlines()
            if line.startswith('| ') and not line.startswith(headers)]
    assert len(rows) == 20
    for row in rows:
        assert row in done.stdout, f'README row not printed by demo: {row}'
    runs = json.loads((tmp_path / 'demo' / 'fig11_graph.json').read_text())
    assert runs['closed_loop']['deviation_mm'] < 0.0124
    for run in runs.values():   # the logs it names are where it says, not in a deleted folder
        assert (Path(run['log_dir']) / 'controller_node.log').is_file(), run['log_dir']
    assert 5.0 < runs['open_loop']['deviation_mm'] < 20.0
    # The model-based controller on the same goal: fewer periods, closer.
    assert runs['model']['outcome'] == 'reached' and runs['model']['periods'] <= 3
    assert runs['model']['deviation_mm'] < runs['closed_loop']['deviation_mm']
    # The same loop on rendered images and the tracker: reached within the 3 um tolerance.
    assert runs['images']['outcome'] == 'reached' and runs['images']['deviation_mm'] < 0.003
    # The paper's rule on a robot with realistic steering reaches too, its steering time counted.
    realistic = runs['realistic_steering']
    assert realistic['outcome'] == 'reached' and realistic['deviation_mm'] < 0.003
    assert realistic['sim_time_s'] > runs['closed_loop']['sim_time_s']
    # The servo mode through the graph: within 0.5 um in one move and one stop, in 8 s at most.
    servo = runs['servo']
    assert servo['outcome'] == 'reached' and servo['deviation_mm'] < 0.0005
    assert servo['periods'] == 1 and servo['sim_time_s'] <= 8.0


def test_a_demo_run_that_fails_keeps_the_logs_it_names(tmp_path, monkeypatch, capsys):
    """A graph run that fails mid-demo: the logs its message names are there afterwards (they
    were in the staged folder the failure removes), and no figure or table is written. The graph
    runs are stood in for: the third one fails as run_graph reports a failure."""
    from omni_micro_bringup import graph
    from omni_micro_bringup.errors import RunFailed
    from omni_micro_bringup.graph import GraphResult
    from omni_micro_cli.cli import main
    from omni_micro_studies import open_loop_figures

    runs: list[Path] = []

    def run_graph(options):
        run_logs = options.log_dir / f'run{len(runs)}'
        run_logs.mkdir(parents=True)
        (run_logs / 'dynamics_node.log').write_text('simulated time has stood at 0.000 s\n')
        runs.append(run_logs)
        if len(runs) == 3:
            raise RunFailed(f'no outcome from controller_node; logs in {run_logs}')
        return GraphResult('completed' if options.open_loop_s else 'reached', '', 8.0, 1.0,
                           run_logs, 1, periods=3, final_x_m=0.1, final_y_m=0.0,
                           final_phi_rad=0.0, goal_m=options.goal_m,
                           route=[(0.0, 0.0, 0.0), (1.0, 0.1, 0.0)],
                           captures=[(1.0, 0.1, 0.0, 'micro')])

    monkeypatch.setattr(graph, 'run_graph', run_graph)
    monkeypatch.setattr(open_loop_figures, 'write_figures',
                        lambda folder, **_: (folder / 'comparison.md').write_text('| result |\n'))
    out = tmp_path / 'demo'
    assert main(['demo', '--out', str(out)]) == 1
    error = capsys.readouterr().err
    named = Path(error.split('logs in ', 1)[1].split()[0].rstrip(';,'))
    assert named == runs[-1] and (named / 'dynamics_node.log').is_file()
    assert sorted(path.name for path in out.iterdir()) == ['logs']


def test_demo_records_each_run_into_a_bag_of_its_own(tmp_path, monkeypatch, capsys):
    """demo --record: each of its six runs is recorded into DIR/fig11_<run> (the recorder and
    its bags are the graph's, tested in tests/graph); an existing bag is refused before anything
    runs. The graph runs are stood in for here: what is checked is what demo asks of them."""
    from omni_micro_bringup import graph
    from omni_micro_bringup.graph import GraphResult
    from omni_micro_cli.cli import main
    from omni_micro_studies import open_loop_figures

    asked: list[tuple[str | None, str, dict]] = []

    def run_graph(options):
        asked.append((options.record and options.record.name, options.vision,
                      options.controller_overrides))
        return GraphResult('completed' if options.open_loop_s else 'reached', '', 8.0, 1.0,
                           options.log_dir, 1, periods=3, final_x_m=0.1, final_y_m=0.0,
                           final_phi_rad=0.0, goal_m=options.goal_m,
                           route=[(0.0, 0.0, 0.0), (1.0, 0.1, 0.0)],
                           captures=[(1.0, 0.1, 0.0, 'micro')])

    monkeypatch.setattr(graph, 'run_graph', run_graph)
    monkeypatch.setattr(open_loop_figures, 'write_figures',
                        lambda folder, **_: (folder / 'comparison.md').write_text('| result |\n'))
    assert main(['demo', '--out', str(tmp_path / 'demo'), '--record', str(tmp_path / 'bags')]) \
        == 0
    assert [bag for bag, _, _ in asked] == [
        'fig11_open_loop', 'fig11_closed_loop', 'fig11_model', 'fig11_images',
        'fig11_realistic_steering', 'fig11_servo']
    assert [vision for _, vision, _ in asked].count('images') == 1
    assert f'bags in {tmp_path / "bags"}/' in capsys.readouterr().out
    # Asked again into the same folder: refused, naming the bag, before any run.
    (tmp_path / 'bags' / 'fig11_servo').mkdir(parents=True)
    (tmp_path / 'bags' / 'fig11_servo' / 'metadata.yaml').write_text('')
    asked.clear()
    assert main(['demo', '--out', str(tmp_path / 'again'), '--record',
                 str(tmp_path / 'bags')]) == 2
    assert asked == [] and 'fig11_' in capsys.readouterr().err
