"""What a newcomer following docs/fleet.md meets: ``--json`` gives standard output as the JSON
document alone (the table and progress on standard error), and a hint a message gives works
(an existing bag: ``--force`` replaces it)."""

from __future__ import annotations

import json
import sys

import numpy as np
import pytest

from omni_micro_cli.cli import main
from omni_micro_cli.outputs import json_alone_on_stdout, print_json

FLEET = ['fleet', '--robots', '2', '--goals-per-robot', '1', '--seed', '0']


def test_with_json_standard_output_is_the_json_document_alone(capsys):
    assert main([*FLEET, '--json']) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)   # the whole of it: one document, nothing around it
    assert summary['outcome'] == 'done' and len(summary['robots']) == 2
    assert 'robot_0  paper' in err and 'goals reached at' in err
    assert main(['simulate', '--theta-deg', '0', '--duration', '2', '--json']) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)['drift_mm'] > 0


def test_without_json_the_table_stays_on_standard_output(capsys):
    assert main(FLEET) == 0
    out, err = capsys.readouterr()
    assert 'robot_0  paper' in out and 'goals reached at' in err


def test_only_print_json_reaches_standard_output_under_json(capsys):
    with json_alone_on_stdout():
        print('a table')
        print_json({'a': 1})
        print('more', file=sys.stdout)
    out, err = capsys.readouterr()
    assert out == '{"a": 1}\n' and err == 'a table\nmore\n'


@pytest.mark.parametrize('door', [FLEET, ['run', '--robots', '2']])
def test_the_force_an_existing_bag_s_message_names_is_taken(door, tmp_path, capsys):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: {}\n')
    assert main([*door, '--record', str(bag)]) == 2
    err = capsys.readouterr().err
    assert 'exists already; give --force to replace it' in err
    assert (bag / 'metadata.yaml').exists()   # refused: nothing touched
    if door[0] == 'fleet':   # the twin writes its bag itself: replaced by a readable one
        assert main([*door, '--record', str(bag), '--force']) == 0
        assert 'recorded' in capsys.readouterr().err
        assert list(bag.glob('*.mcap'))
    else:   # through the graph: the flag is taken (the run itself is tests/graph's)
        assert main([*door, '--record', str(bag), '--force', '--tasks',
                     str(tmp_path / 'missing.yaml')]) == 2
        assert 'unknown' not in capsys.readouterr().err


def test_the_json_and_the_table_say_each_goal_with_its_camera_s_own_error(capsys):
    assert main([*FLEET[:3], '--goals-per-robot', '2', '--seed', '0', '--json']) == 0
    out, err = capsys.readouterr()
    summary = json.loads(out)
    for robot in summary['robots']:
        micro, macro = robot['goal_results']
        assert micro['camera'] == 'micro' and macro['camera'] == 'macro'
        # Where the goal was, how close it was reached, and what the camera can tell there.
        assert abs(micro['goal_mm'][0] - 100.0) <= 0.5 and abs(micro['goal_mm'][1]) <= 0.5
        assert micro['deviation_um'] <= 3.0 and micro['capture_95_um'] == pytest.approx(0.35,
                                                                                     abs=0.01)
        assert macro['deviation_um'] <= 50.0 and macro['capture_95_um'] == pytest.approx(
            26.39, abs=0.01)
        assert [goal['reached_at_s'] for goal in robot['goal_results']] == robot['reached_at_s']
        assert -180.0 <= robot['final_phi_deg'] <= 180.0
    header, *rows = [line for line in err.splitlines() if line.startswith('robot')]
    assert 'micro um' in header and 'macro um' in header
    micro = summary['robots'][0]['goal_results'][0]
    assert f"{micro['deviation_um']:.2f}+-0.35" in rows[0]
    # What the plan keeps and what the run measured, each named.
    assert '(robots 0 and 1; planned 12 mm or more)' in err


def test_track_s_help_gives_the_exit_code_of_a_robot_never_named(capsys):
    with pytest.raises(SystemExit):
        main(['track', '--help'])
    said = ' '.join(capsys.readouterr().out.split())
    assert '1 when none did (with --robots: when a robot never was, named)' in said


def test_overlapping_routes_stay_visible_each_robot_in_its_colour(tmp_path):
    """Two robots driven along the same line: both colours show along it, each start and end
    labelled, the whole platform and the micro field close up in the picture."""
    import io

    from matplotlib.image import imread

    from omni_micro_vision.fleet_figure import DrawnRobot, colour_of, fleet_routes_png, route_style

    line = np.column_stack([np.linspace(0.0, 0.1, 200), np.zeros(200)])
    robots = [DrawnRobot(k, f'robot_{k}', line, np.array([[0.1, 0.0]]), 1) for k in (0, 1)]
    assert route_style(0, 2) != route_style(1, 2) and route_style(0, 1) == '-'
    pixels = imread(io.BytesIO(fleet_routes_png(robots, 'overlap')))[:, :, :3]
    for k in (0, 1):
        near = np.all(np.abs(pixels - np.array(colour_of(k))) < 0.05, axis=2)
        assert near.sum() > 200, f'robot_{k} hidden'
    assert len(fleet_routes_png(robots[:1], 'one')) > 0


def test_a_robot_among_others_draws_its_route_in_its_colour():
    from omni_micro_vision.camera import DEFAULT_RIG
    from omni_micro_vision.scene import FLEET_COLOURS, ROUTE, Scene

    for scene, colour in ((Scene(DEFAULT_RIG), ROUTE),
                          (Scene(DEFAULT_RIG, robot_colour=FLEET_COLOURS[2], label='robot_2'),
                           (*FLEET_COLOURS[2][:3], 1.0))):
        for x in (0.0, 0.01, 0.02):
            scene.on_odometry(x, 0.0, 0.0)
        assert {shape.colour for shape in scene.route_shapes(only_last=False)} == {colour}


@pytest.mark.parametrize(('robots', 'tasks', 'named'), [
    ('[{start_mm: [0, 0]}, {start_mm: [40, 0]}]',
     '{robot_0: [{goal_mm: [500, 0]}], robot_1: [{goal_mm: [40, 40]}]}', 'off the platform'),
    ('[{start_mm: [0, 0]}, {start_mm: [5, 0]}]',
     '{robot_0: [{goal_mm: [60, 0]}], robot_1: [{goal_mm: [40, 40]}]}', 'start 5.00 mm apart'),
    ('[{start_mm: [0, 0]}, {start_mm: [40, 0]}]',
     '{robot_0: [{goal_mm: [60, 0], after: [1, 5]}], robot_1: [{goal_mm: [40, 40]}]}',
     'waits for robot 1'),
    ('[{start_mm: [0, 0]}, {start_mm: [40, 0]}]',
     '{robot_0: [{goal_mm: [60, 0], after: [1, 0]}], '
     'robot_1: [{goal_mm: [40, 40], after: [0, 0]}]}', 'cycle')],
    ids=['goal off the platform', 'starting touching', 'after naming no goal', 'a cycle'])
def test_a_refused_fleet_leaves_nothing_on_disk(robots, tasks, named, tmp_path, capsys):
    (tmp_path / 'robots.yaml').write_text(f'robots: {robots}\n')
    (tmp_path / 'tasks.yaml').write_text(f'tasks: {tasks}\n')
    bag = tmp_path / 'bags' / 'factory'
    assert main(['fleet', '--robots', str(tmp_path / 'robots.yaml'), '--tasks',
                 str(tmp_path / 'tasks.yaml'), '--record', str(bag)]) == 2
    said = capsys.readouterr().err.strip()
    assert named in said and said.count('\n') == 0, said
    assert not (tmp_path / 'bags').exists()
