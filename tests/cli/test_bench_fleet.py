"""`bench-fleet`'s arithmetic and verdicts, on runs whose results are given: robot-seconds per
wall second, the ratio against one robot's in the same layout, the targets met or not, and a
run that ends otherwise than drawn (a contact) failing the command. The runs themselves are the
fleet graph's, tested in tests/graph."""

from __future__ import annotations

import json
from types import SimpleNamespace

from omni_micro_cli.cli import build_parser
from omni_micro_cli.commands import bench_fleet


def given_runs(monkeypatch, rtf_of, outcome_of=lambda count, label: 'timeout'):
    calls = []

    def one_run(count, composed, containers, seed, sim_s, scratch):
        label = next(label for label, c, n in bench_fleet.LAYOUTS
                     if (c, n) == (composed, containers))
        calls.append((count, label, sim_s))
        return SimpleNamespace(outcome=outcome_of(count, label), sim_time_s=sim_s,
                               wall_time_s=sim_s / rtf_of(count, label))
    monkeypatch.setattr(bench_fleet, 'one_run', one_run)
    return calls


def test_robot_seconds_against_one_robot_and_the_targets(monkeypatch, capsys):
    rtf = {1: 20.0, 16: 2.5, 42: 0.4}
    calls = given_runs(monkeypatch, lambda count, label: rtf[count]
                       * (0.5 if label == 'separate processes' else 1.0))
    args = build_parser().parse_args(['bench-fleet', '--robot-counts', '16,42',
                                      '--sim-seconds', '5', '--json'])
    assert args.handler(args) == 0
    # One robot is always run, as the reference; 42 robots are composed only (the default).
    assert [(count, label) for count, label, _ in calls] == [
        (count, label) for count in (1, 16, 42) for label, composed, _ in bench_fleet.LAYOUTS
        if composed or count <= 16]
    assert {sim_s for *_, sim_s in calls} == {5.0}
    report = json.loads(capsys.readouterr().out)
    row = next(row for row in report['runs']
               if row['robots'] == 16 and row['layout'] == 'composed, one per core')
    assert row['robot_seconds_per_wall_s'] == 40.0 and row['against_one_robot'] == 2.0
    assert {(t['robots'], t['layout']): t['met'] for t in report['targets']} == {
        (16, 'composed, one per core'): True, (16, 'separate processes'): True,
        (42, 'composed, one per core'): False}


def test_a_run_that_ends_otherwise_than_drawn_fails_the_benchmark(monkeypatch, capsys):
    given_runs(monkeypatch, lambda count, label: 10.0,
               lambda count, label: 'contact' if count == 2 else 'done')
    args = build_parser().parse_args(['bench-fleet', '--robot-counts', '2'])
    assert args.handler(args) == 1
    assert '2 robots, separate processes: ended contact, not as drawn' in capsys.readouterr().err
