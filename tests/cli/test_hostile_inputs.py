"""Rounds 2 and 3 of hostile inputs: what still ended in a traceback, runaway memory or a
half-written file; paths the system refuses, a mistyped command or flag, angles no float can
hold, numbers YAML 1.1 takes for strings. Each case exits 2 with one line naming the value (or
1 saying why the work failed) and leaves nothing behind. In-process: nothing here starts a
graph."""

from __future__ import annotations

import math
import os
from pathlib import Path

import pytest

from omni_micro_cli.cli import main
from omni_micro_common.params import read_yaml


def exit_code_and_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    try:
        code = main(argv)
    except SystemExit as stop:   # argparse's refusals
        code = int(stop.code or 0)
    err = capsys.readouterr().err.strip()
    return code, err


def assert_one_line_naming(err: str, *named: str) -> None:
    last = err.splitlines()[-1]
    assert 'Traceback' not in err, err
    for text in named:
        assert text in last, last


@pytest.mark.parametrize(('argv', 'named'), [
    (['analyze', 'x', '--out', 'y', '--animate', 'gif', '--frames', '1000000000'],
     ['--frames', '1000000000', '[1, 2000]']),
    (['figures', '--out', 'OUT', '--offset-step-deg', '1e-9'], ['--offset-step-deg', '1e-09']),
    (['run', '--goal-mm', '1,0', '--view', '--view-port', '70000'], ['70000', '65535']),
    (['demo', '--view', '--view-port', '70000'], ['70000', '65535']),
    (['soak', '--view', '--view-port', '70000'], ['70000', '65535']),
    (['run', '--goal-mm', '1,0', '--rtf', '1e-300'], ['--rtf', '1e-300', '0.001']),
    (['replay', 'x', '--rate', '1e-300'], ['--rate', '1e-300']),
    (['replay', 'x', '--domain-id', '999'], ['999', '232']),
    (['identify', 'x', '--fit', 'xi2,xi2'], ['xi2 named twice']),
    (['track', 'x', '--max-frames', '-1'], ["'-1'", '>= 1']),
    (['track', 'x', '--max-frames', '0'], ["'0'", '>= 1']),
    (['analyze', 'x', '--out', 'y', '--frames', '-1'], ["'-1'", '[1, 2000]']),
    (['compare-controllers', '--cases', '99999999999'], ['--cases']),
])
def test_a_value_out_of_bounds_is_refused_naming_it(argv, named, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, err = exit_code_and_error([a.replace('OUT', str(tmp_path / 'o')) for a in argv],
                                    capsys)
    assert code == 2
    assert_one_line_naming(err, *named)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(('argv', 'named'), [
    (['run', '--goal-mm', '1,0', '--record', 'FILE/bag'], ['is under', 'which is a file']),
    (['run', '--goal-mm', '1,0', '--log-dir', 'FILE'], ['exists and is a file']),
    (['soak', '--out', 'FILE'], ['exists and is a file']),
    (['study', 'S', '--out', 'FILE/x'], ['is under']),
    (['analyze', 'x', '--out', 'FILE'], ['exists and is a file']),
    (['figures', '--out', 'FILE/x'], ['is under']),
    (['compare-controllers', '--out', 'FILE'], ['exists and is a file']),
    (['identify', 'x', '--write-params', 'DIR'], ['is a folder (expected a file)']),
    (['track', 'x', '--csv', 'DIR'], ['is a folder (expected a file)']),
    (['record', 'FILE/bag'], ['is under']),
])
def test_an_output_path_that_cannot_be_written_is_refused_before_anything_runs(
        argv, named, tmp_path, capsys):
    (tmp_path / 'file').write_text('mine')
    (tmp_path / 'dir').mkdir()
    (tmp_path / 's.yaml').write_text('name: s\n')
    swap = {'FILE': str(tmp_path / 'file'), 'DIR': str(tmp_path / 'dir'),
            'S': str(tmp_path / 's.yaml')}
    code, err = exit_code_and_error(
        [next((a.replace(k, v) for k, v in swap.items() if a.startswith(k)), a)
         for a in argv], capsys)
    assert code == 2
    assert_one_line_naming(err, *named)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['dir', 'file', 's.yaml']
    assert (tmp_path / 'file').read_text() == 'mine' and not any((tmp_path / 'dir').iterdir())


NOT_UTF8 = b'controller_node:\n  ros__parameters:\n    tolerance_m: 3.0e-6  # \xb5m\n'


def test_params_and_study_files_that_are_not_utf8_are_named(tmp_path, capsys):
    params = tmp_path / 'latin1.yaml'
    params.write_bytes(NOT_UTF8)
    for argv in (['run', '--goal-mm', '100,0', '--params', str(params),
                  '--log-dir', str(tmp_path / 'logs')],
                 ['study', str(params), '--out', str(tmp_path / 'study')]):
        code, err = exit_code_and_error(argv, capsys)
        assert code == 2
        assert_one_line_naming(err, str(params), 'not UTF-8')
    assert not (tmp_path / 'study').exists() and not (tmp_path / 'logs').exists()


def test_a_damaged_runs_file_is_named_under_resume_and_rerun(tmp_path, capsys):
    from omni_micro_studies.execute import RUNS_FILE, prepare_directory
    from omni_micro_studies.spec import parse_study

    out = tmp_path / 'study'
    prepare_directory(parse_study('name: s\nscenario: open_loop\n', 's'), out)
    (out / RUNS_FILE).write_bytes(b'PAR1 this is not a table')
    for argv in (['study', '--resume', str(out)], ['study', '--rerun', str(out), '0']):
        code, err = exit_code_and_error(argv, capsys)
        assert code == 2
        assert_one_line_naming(err, str(out / RUNS_FILE), 'not a readable table')


def test_figures_into_a_folder_of_the_users_lists_only_what_it_wrote(tmp_path, capsys):
    out = tmp_path / 'figs'
    out.mkdir()
    (out / 'notes.txt').write_text('mine')
    code = main(['figures', '--out', str(out), '--angle-step-deg', '30',
                 '--offset-step-deg', '10'])
    wrote = capsys.readouterr().out.strip().splitlines()[-1]
    assert code == 0 and wrote.startswith('wrote ') and 'notes.txt' not in wrote
    assert (out / 'notes.txt').read_text() == 'mine'


def test_a_reference_that_times_out_is_one_line(capsys):
    code, err = exit_code_and_error(['bench', '--repeats', '1', '--batch', '2',
                                     '--reference-timeout', '0.001'], capsys)
    assert code == 1
    assert_one_line_naming(err, 'did not finish within --reference-timeout 0.001 s')


def test_an_unexpected_error_is_one_line_with_the_traceback_in_a_file(monkeypatch, capsys):
    from omni_micro_cli.commands import simulate

    def broken(args: object) -> int:
        raise ZeroDivisionError('the unforeseen')

    monkeypatch.setattr(simulate, 'run', broken)
    code, err = exit_code_and_error(['simulate', '--theta-deg', '0', '--duration', '1'], capsys)
    assert code == 1
    assert len(err.splitlines()) == 1
    assert 'failed unexpectedly: ZeroDivisionError: the unforeseen' in err
    log = Path(err.split('traceback in ')[1].split(';')[0])
    assert 'Traceback' in log.read_text() and 'ZeroDivisionError' in log.read_text()
    log.unlink()
    with pytest.raises(ZeroDivisionError):   # asked for: the traceback itself
        main(['--debug', 'simulate', '--theta-deg', '0', '--duration', '1'])


def test_track_on_a_topic_that_is_not_an_image_names_its_type(tmp_path, capsys):
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message

    from omni_micro_tools.bags import open_writer
    from omni_micro_tools.topics import GRAPH_TOPICS

    bag = tmp_path / 'bag'
    writer, connections = open_writer(bag, 'mcap', {'/odom': GRAPH_TOPICS['/odom']})
    writer.write(connections['/odom'], 1, serialize_message(Odometry()))
    writer.close()
    code, err = exit_code_and_error(['track', str(bag), '--image-topic', '/odom'], capsys)
    assert code == 2
    assert_one_line_naming(err, '/odom', 'nav_msgs/msg/Odometry', 'not sensor_msgs/msg/Image')


# -- round 3 --------------------------------------------------------------------------------------
LONG = 'x' * 300


@pytest.mark.parametrize(('argv', 'named'), [
    (['graph', '--out', f'{LONG}.svg'], ['--out', 'File name too long']),
    (['run', '--goal-mm', '1,0', '--record', LONG], ['--record', 'File name too long']),
    (['study', 'S', '--out', LONG], ['--out', 'File name too long']),
    (['run', '--goal-mm', '1,0', '--params', f'{LONG}.yaml'],
     ['params file', 'cannot be read: File name too long']),
    (['identify', LONG], ['cannot be read: File name too long']),
    (['run', '--goal-mm', '1,0', '--record', 'LOOP'], ['--record', 'loop of links']),
    (['compare-controllers', '--out', 'LOOP'], ['--out', 'loop of links']),
])
def test_a_path_the_system_refuses_is_one_line_and_exit_2(argv, named, tmp_path, capsys,
                                                         monkeypatch):
    monkeypatch.chdir(tmp_path)
    os.symlink('LOOP2', 'LOOP')
    os.symlink('LOOP', 'LOOP2')
    code, err = exit_code_and_error(argv, capsys)
    assert code == 2, err
    assert len(err.splitlines()) == 1, err
    assert_one_line_naming(err, *named)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['LOOP', 'LOOP2']


@pytest.mark.parametrize(('argv', 'line'), [
    (['rn'], "omni-micro: error: 'rn' is not a command; did you mean run? (omni-micro --help "
             'lists them)'),
    (['run', '--goal', '100,0'], 'omni-micro run: error: unrecognized arguments: --goal 100,0; '
                                 'did you mean --goal-mm? (omni-micro run --help lists the '
                                 'arguments)'),
    (['fleet', '--robots', '2', '--bogus'], 'omni-micro fleet: error: unrecognized arguments: '
                                            '--bogus (omni-micro fleet --help lists the '
                                            'arguments)'),
    (['fleet', '--robots', '-1'], "omni-micro fleet: error: --robots must be a whole number "
                                  "1..42 or a YAML file, got '-1'"),
    (['run'], 'omni-micro run: error: --goal-mm X,Y is needed (or --robots N|FILE for several '
              'robots)'),
    (['run', '--robots', '3', '--open-loop', '3', '--vision', 'images'],
     "omni-micro run: error: --open-loop: a single robot's run only; with --robots give "
     '--tasks, --controller, --vision, --seed, --rtf, --timeout, --log-dir, --record, '
     '--record-images, --force, --composed, --no-markers, --view, --respawn, the camera '
     "faults, --json, --quiet, --goals-per-robot, --max-sim-time, --plot, --params and the "
     "bench's options"),
    (['run', '--robots', '3', '--tolerance-um', '5'],
     "omni-micro run: error: --tolerance-um: a single robot's run only; with --robots give "
     '--tasks, --controller, --vision, --seed, --rtf, --timeout, --log-dir, --record, '
     '--record-images, --force, --composed, --no-markers, --view, --respawn, the camera '
     "faults, --json, --quiet, --goals-per-robot, --max-sim-time, --plot, --params and the "
     "bench's options"),
    (['fleet', '--vision', 'images'], "omni-micro fleet: error: --vision images is a node "
                                      "graph's: give it with --graph"),
    (['fleet', '--composed'], "omni-micro fleet: error: --composed is a node graph's: give it "
                              'with --graph'),
    (['fleet', '--view'], "omni-micro fleet: error: --view is a node graph's: give it with "
                          '--graph'),
    (['fleet', '--respawn'], "omni-micro fleet: error: --respawn is a node graph's: give it "
                             'with --graph'),
    (['fleet', '--record-images'], "omni-micro fleet: error: --record-images is a node "
                                   "graph's: give it with --graph"),
    (['fleet', '--graph', '--record-images', '--vision', 'images'],
     'omni-micro fleet: error: --record-images needs --record BAG and images to record: '
     '--vision images or --camera external'),
    (['fleet', '--drop-captures', '0.3'], "omni-micro fleet: error: fault injection is a node "
                                          "graph's (vision_node's): give it with --graph"),
    (['run', '--robots', '2', '--vision', 'images', '--late-captures', '0.2'],
     "omni-micro run: error: fault injection (faults.camera, faults.delay_s) is vision_node's: "
     'it needs --vision model, got --vision images'),
    (['run', '--robots', '2', '--respawn', '--composed'],
     'omni-micro run: error: --respawn restarts a crashed node in a process of its own; with '
     '--composed the loop shares one process: choose one of them'),
    (['view', '--robots', 'robot 1'], "omni-micro view: error: argument --robots: 'robot 1': "
                                      'expected a number of robots or namespaces such as '
                                      'robot_0,robot_1 (omni-micro view --help lists the '
                                      'arguments)'),
    (['run', '--goal-mm', '1,0', '--tasks', 'tasks.yaml'],
     'omni-micro run: error: --tasks: for several robots; give --robots N|FILE'),
    (['fleet', '--rtf', '2'], 'omni-micro fleet: error: --rtf paces the node graph: give it with '
                              '--graph'),
    (['run', '--robots', '2', '--camera', 'external'],
     'omni-micro run: error: several robots on the bench take both --camera external and '
     '--robot external (got --camera external --robot simulated): a real camera cannot see '
     'simulated robots, nor a simulated one real ones'),
    (['run', '--robots', '2', '--camera', 'external', '--robot', 'external', '--composed'],
     'omni-micro run: error: --composed: not with real robots (no simulated robot to hold, '
     'draw or fault); leave them out'),
    (['run', '--goal-mm', '1,0', '--stop-gap-mm', '12'],
     'omni-micro run: error: --stop-gap-mm: for several robots; give --robots N|FILE'),
    (['run', '--robots', '2', '--camera', 'external', '--robot', 'external', '--stop-gap-mm',
      '5'],
     "omni-micro run: error: argument --stop-gap-mm: expected at least 9 mm (two robots' discs "
     "touch there), got '5' (omni-micro run --help lists the arguments)"),
    (['fleet', '--camera', 'external', '--robot', 'external'],
     "omni-micro fleet: error: --params and the bench (--camera, --robot external) are a node "
     "graph's: give them with --graph"),
    (['fleet', '--graph', '--camera', 'external', '--robot', 'external', '--rtf', '2'],
     'omni-micro fleet: error: with an external camera or robot the graph runs at real time: '
     '--rtf must be 1, got 2'),
    (['run', '--goal-mm', '1,0', '--seed', '100000000000000000000000'],
     "omni-micro run: error: argument --seed: expected a whole number in [0, "
     "9223372036854775807] (a seed: a ROS integer parameter), got '100000000000000000000000' "
     '(omni-micro run --help lists the arguments)'),
    (['run', '--goal-mm', '1,0', '--open-loop', '7', '--controller', 'open-loop'],
     'omni-micro run: error: --open-loop S makes one move of S seconds and --controller '
     'open-loop one of the time to the goal: leave one of them out'),
    (['run', '--goal-mm', '1,0', '--open-loop', '1e9'],
     "omni-micro run: error: argument --open-loop: expected at most 60 s (a minute at cruise "
     "speed runs off any platform), got '1e9' (omni-micro run --help lists the arguments)"),
    (['simulate', '--theta-deg', '1e20', '--duration', '1'],
     "omni-micro simulate: error: argument --theta-deg: expected a number in [-360, 360], got "
     "'1e20' (omni-micro simulate --help lists the arguments)"),
    (['simulate', '--theta-deg', '90', '--duration', '1', '--steer-from-deg', '1e20'],
     "omni-micro simulate: error: argument --steer-from-deg: expected a number in [-360, 360], "
     "got '1e20' (omni-micro simulate --help lists the arguments)"),
])
def test_a_mistake_on_the_command_line_is_one_line_without_the_usage(argv, line, capsys):
    """argparse printed up to 11 lines of usage before the line that matters, and took
    ``--goal`` for ``--goal-mm`` by prefix."""
    code, err = exit_code_and_error(argv, capsys)
    assert code == 2
    assert err == line


def test_params_files_read_numbers_as_ros_does(tmp_path):
    """YAML 1.1 reads 3e0 and 1.0e300 as strings; ROS's parser and -p read numbers."""
    path = tmp_path / 'p.yaml'
    path.write_text('a: 3e0\nb: 1.0e300\nc: 3\nd: -2.5E-3\ne: .5\nf: 1e\ng: e3\n')
    values = read_yaml(path)
    assert values == {'a': 3.0, 'b': 1.0e300, 'c': 3, 'd': -2.5e-3, 'e': 0.5, 'f': '1e',
                      'g': 'e3'}
    assert isinstance(values['a'], float) and math.isfinite(values['b'])


def test_identify_on_a_bag_without_a_move_fails_with_exit_1_as_its_help_says(tmp_path, capsys):
    """A valid bag with too little in it is a failed identification (1), not a bad argument
    (2, what it exited with)."""
    from nav_msgs.msg import Odometry
    from rclpy.serialization import serialize_message

    from omni_micro_tools.bags import open_writer
    from omni_micro_tools.topics import GRAPH_TOPICS

    bag = tmp_path / 'still'
    writer, connections = open_writer(bag, 'mcap', {'/odom': GRAPH_TOPICS['/odom']})
    writer.write(connections['/odom'], 0, serialize_message(Odometry()))
    writer.close()
    code, err = exit_code_and_error(['identify', str(bag)], capsys)
    assert code == 1
    assert err == (f"omni-micro identify: failed: '{bag}' has no move on /wheel_trajectory: "
                   'nothing to identify')


def test_a_platform_of_no_size_is_refused_before_anything_starts(tmp_path, capsys):
    """platform.size_m [0, 0] was accepted: every goal then lay outside it."""
    params = tmp_path / 'p.yaml'
    params.write_text('controller_node:\n  ros__parameters:\n    platform:\n'
                      '      size_m: [0.0, 0.0]\n')
    code, err = exit_code_and_error(['run', '--goal-mm', '100,0', '--params', str(params),
                                     '--log-dir', str(tmp_path / 'logs')], capsys)
    assert code == 2
    assert err == ('omni-micro run: error: platform.size_m must be two finite numbers > 0 '
                   '(metres), got [0.0, 0.0]')
    assert not (tmp_path / 'logs').exists()


def test_a_second_sigterm_does_not_interrupt_the_first_ones_clean_up():
    """timeout signals a process and its group: the pair raised two KeyboardInterrupts, the
    second inside the first's clean-up (a traceback, 1 run in 6)."""
    from omni_micro_cli.cli import _Interrupt

    handler = _Interrupt()
    with pytest.raises(KeyboardInterrupt):
        handler(15, None)
    handler(15, None)   # the second of the pair: no new interruption


def test_a_view_address_beyond_loopback_says_who_can_connect():
    from omni_micro_cli.errors import UsageError
    from omni_micro_cli.graph_arguments import check_view_host

    assert check_view_host('127.0.0.1') is None
    assert 'any machine that can reach this one' in str(check_view_host('0.0.0.0'))
    with pytest.raises(UsageError, match=r"an IP address such as 127\.0\.0\.1, got 'lab'"):
        check_view_host('lab')
