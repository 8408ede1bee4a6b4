"""Nodes forked from the zygote (omni_micro_bringup.warm_start) get what a started process gets,
and leave as it would: the same argv, environment, working directory, session, descriptors and
process name, the same exit code for each way out, and nothing left when the orchestrator dies.
Each case is run both ways, warm and cold (subprocess), on a probe entry point."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from omni_micro_bringup import warm_start
from omni_micro_bringup.node_spec import NodeSpec, composed, process_argv
from omni_micro_bringup.processes import node_environment
from omni_micro_bringup.warm_start import WARM_START_ENV, WarmProcess, entry_point_of, start_warm

pytestmark = pytest.mark.slow   # it starts processes
PROBE = Path(__file__).parents[1] / 'support' / 'warm_probe.py'


@pytest.fixture
def probe_env(tmp_path):
    lifeline_read, lifeline_write = os.pipe()
    env = {**node_environment(7, tmp_path), 'PYTHONPATH': str(PROBE.parent),
           'PROBE_LIFELINE_FD': str(lifeline_read), WARM_START_ENV: '1'}
    yield env, lifeline_read
    os.close(lifeline_read)
    os.close(lifeline_write)


def start(how: str, word: str, env: dict[str, str],
          lifeline: int) -> tuple[WarmProcess | subprocess.Popen[str], dict]:
    """The probe started warm or cold; its process and its first line (what it was given)."""
    process: WarmProcess | subprocess.Popen[str] | None
    if how == 'warm':
        process = start_warm([str(PROBE.with_suffix('')), word], env, (lifeline,),
                             entry_point='warm_probe:main')
        assert process is not None
    else:
        process = subprocess.Popen([sys.executable, str(PROBE), word], env=env, text=True,
                                   stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                   stderr=subprocess.STDOUT, start_new_session=True,
                                   pass_fds=(lifeline,))
    assert process.stdout is not None
    return process, json.loads(process.stdout.readline())


def finish(process: WarmProcess | subprocess.Popen[str]) -> tuple[int, str]:
    code = process.wait(30.0)
    assert process.stdout is not None
    rest = process.stdout.read()
    process.stdout.close()
    return code, rest


def test_a_warm_node_is_given_what_a_started_one_is(probe_env, tmp_path, monkeypatch):
    env, lifeline = probe_env
    monkeypatch.chdir(tmp_path)
    given = {}
    for how in ('warm', 'cold'):
        process, given[how] = start(how, '0', env, lifeline)
        assert finish(process) == (0, '')
    warm, cold = given['warm'], given['cold']
    assert warm['argv'] == [str(PROBE.with_suffix('')), '0']
    assert warm['cwd'] == cold['cwd'] == str(tmp_path)
    assert warm['domain'] == cold['domain'] == '7'
    assert warm['own_session'] and cold['own_session']
    assert warm['stdin_is_null'] and cold['stdin_is_null']
    # Only stdio and the descriptor handed over, at its number (and the probe's own listing).
    assert warm['open_fds'] == cold['open_fds'] and warm['lifeline_open']
    assert warm['name'] == 'warm_probe'   # what `top` and `pgrep` show
    # What `ps aux`, `htop` and `pgrep -f` show: the script and its arguments, as started.
    assert warm['cmdline'] == f'{PROBE.with_suffix("")} 0'
    assert cold['cmdline'] == f'{sys.executable} {PROBE} 0'
    assert warm['pid'] != os.getpid() and warm['pid'] > 0


@pytest.mark.parametrize('spec', [
    NodeSpec('omni_micro_vision', 'vision_node', {'seed': 3}, namespace='robot_1',
             remaps=('__ns:=/robot_1',)),
    *composed([NodeSpec('omni_micro_sim', 'dynamics_node', {'paused': True}),
               NodeSpec('omni_micro_control', 'controller_node')])],
    ids=['a node', 'the container'])
def test_a_warm_node_is_found_by_pgrep_f_as_ros2_run_would_start_it(spec, probe_env):
    """A node's own command line (the container's with each hosted node's module and ROS
    arguments), run on the probe: ``pgrep -f`` finds it by its executable and arguments."""
    env, lifeline = probe_env
    argv = [*process_argv(spec), '0']
    process, given = start_warm_argv(argv, env, lifeline)
    assert finish(process) == (0, '')
    assert given['cmdline'] == ' '.join(argv)
    assert given['name'] == Path(argv[0]).name[:15]
    assert given['invocation'] == argv[0]   # its ROS log file is named by it, as started
    assert f'{spec.executable} --ros-args' in given['cmdline'] or all(
        f'{hosted.package}.{hosted.executable} --ros-args' in given['cmdline']
        for hosted in spec.hosts)


def start_warm_argv(argv: list[str], env: dict[str, str], lifeline: int) -> tuple[WarmProcess,
                                                                                    dict]:
    process = start_warm(argv, env, (lifeline,), entry_point='warm_probe:main')
    assert process is not None and process.stdout is not None
    return process, json.loads(process.stdout.readline())


@pytest.mark.parametrize('ending', ['3', 'raise', 'SIGINT', 'SIGTERM', 'SIGKILL'])
def test_each_way_out_gives_the_exit_code_a_started_process_gives(probe_env, ending):
    env, lifeline = probe_env
    codes, outputs = {}, {}
    for how in ('warm', 'cold'):
        process, _ = start(how, ending if ending in ('3', 'raise') else 'sleep', env, lifeline)
        if ending.startswith('SIG'):
            assert process.stdout is not None
            assert process.stdout.readline().strip() == 'waiting'
            assert process.poll() is None
            process.send_signal(getattr(signal, ending))
        codes[how], outputs[how] = finish(process)
        assert process.poll() == codes[how]
    assert codes['warm'] == codes['cold'] == {
        '3': 3, 'raise': 1, 'SIGINT': -signal.SIGINT, 'SIGTERM': -signal.SIGTERM,
        'SIGKILL': -signal.SIGKILL}[ending]
    if ending == 'raise':
        assert 'RuntimeError: the probe fails as asked' in outputs['warm']


def test_a_wait_that_times_out_says_so_and_the_node_goes_on(probe_env):
    env, lifeline = probe_env
    process, _ = start('warm', 'sleep', env, lifeline)
    with pytest.raises(subprocess.TimeoutExpired):
        process.wait(0.2)
    assert process.poll() is None
    process.send_signal(signal.SIGKILL)
    assert finish(process)[0] == -signal.SIGKILL


ORCHESTRATOR = f'''
import os, sys, time
sys.path.insert(0, {str(PROBE.parent)!r})
from omni_micro_bringup.warm_start import start_warm
env = dict(os.environ, PYTHONPATH={str(PROBE.parent)!r}, OMNI_MICRO_WARM_START='1')
read_end, write_end = os.pipe()
env['PROBE_LIFELINE_FD'] = str(read_end)
process = start_warm(['probe', 'wait'], env, (read_end,), entry_point='warm_probe:main')
print(process.stdout.readline(), end='', flush=True)
time.sleep(60)
'''


def test_the_zygote_and_its_nodes_leave_with_a_killed_orchestrator(tmp_path):
    """SIGKILL of the orchestrator: the zygote reads its socket's end, the node its lifeline's."""
    orchestrator = subprocess.Popen([sys.executable, '-c', ORCHESTRATOR], text=True,
                                    stdout=subprocess.PIPE, env=node_environment(7, tmp_path))
    assert orchestrator.stdout is not None
    try:
        given = json.loads(orchestrator.stdout.readline())
        zygote = int(Path(f'/proc/{given["pid"]}/stat').read_text().rsplit(')', 1)[1].split()[1])
        assert zygote not in (orchestrator.pid, 1)
    finally:
        orchestrator.kill()
        orchestrator.wait()
    orchestrator.stdout.close()
    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline and any(Path(f'/proc/{pid}').exists()
                                              for pid in (zygote, given['pid'])):
        time.sleep(0.05)
    for pid in (zygote, given['pid']):
        assert not Path(f'/proc/{pid}').exists() or \
            Path(f'/proc/{pid}/stat').read_text().rsplit(')', 1)[1].split()[0] == 'Z', pid


def test_nodes_start_warm_unless_told_not_to_and_cold_when_not_ours(probe_env, monkeypatch,
                                                                     tmp_path):
    env, lifeline = probe_env
    monkeypatch.delenv(WARM_START_ENV, raising=False)
    unset = {k: v for k, v in env.items() if k != WARM_START_ENV}
    warm = start_warm([str(PROBE), '0'], unset, (lifeline,), entry_point='warm_probe:main')
    assert isinstance(warm, WarmProcess)
    assert finish(warm)[0] == 0
    # Told so by the run's environment or by the orchestrator's own.
    assert start_warm([str(PROBE), '0'], {**env, WARM_START_ENV: '0'}, (lifeline,),
                      entry_point='warm_probe:main') is None
    monkeypatch.setenv(WARM_START_ENV, '0')
    assert start_warm([str(PROBE), '0'], unset, (lifeline,),
                      entry_point='warm_probe:main') is None
    # An installed node of ours, run by this interpreter: warm. Another interpreter's: cold.
    ours = Path(sys.executable).parent / 'dynamics_node'
    assert entry_point_of(ours) == 'omni_micro_sim.dynamics_node:main'
    theirs = tmp_path / 'dynamics_node'
    theirs.write_text('#!/usr/bin/python3\n' + ours.read_text().split('\n', 1)[1])
    assert entry_point_of(theirs) is None
    assert entry_point_of(tmp_path / 'missing') is None


def test_one_zygote_per_environment_its_imports_see(probe_env):
    env, _ = probe_env
    first = warm_start._zygote_for(env)
    assert warm_start._zygote_for({**env, 'ROS_DOMAIN_ID': '8', 'ROS_LOG_DIR': '/x',
                                   'PYTEST_CURRENT_TEST': 'another'}) is first
    other = warm_start._zygote_for({**env, 'OPENBLAS_NUM_THREADS': '2'})
    assert other is not first
    assert first.process.poll() is not None or first.process.wait(5.0) == 0   # it had no child


def test_the_zygote_forks_from_one_thread_without_ros_and_with_the_kernels_loaded(probe_env):
    """fork copies only the calling thread: a pool an import had started (OpenBLAS's, numba's,
    or LTTng-UST's two, which rclpy's tracing library starts) would leave the child its locks
    held. The zygote loads nothing of ROS (each child its own rclpy and Fast DDS), and the
    dynamics' kernels come loaded."""
    env, lifeline = probe_env
    process, given = start('warm', '0', env, lifeline)
    assert finish(process) == (0, '')
    assert given['compiled_kernels'] > 0
    zygote = warm_start._zygote_for(env).process.pid
    status = Path(f'/proc/{zygote}/status').read_text()
    assert re.search(r'^Threads:\s+1$', status, re.MULTILINE), status
    assert 'librcl.so' not in Path(f'/proc/{zygote}/maps').read_text()


def test_a_forked_copy_of_the_orchestrator_starts_its_own_zygote_and_leaves_ours_alone(
        probe_env):
    """A process forked from the orchestrator (multiprocessing's default on Linux) inherits the
    socket to the zygote: speaking or closing on it would break the orchestrator's nodes."""
    env, lifeline = probe_env
    ours = warm_start._zygote_for(env)
    child = os.fork()
    if child == 0:
        code = 1
        try:
            theirs = warm_start._zygote_for(env)
            forked = start_warm([str(PROBE.with_suffix('')), '5'], env, (lifeline,),
                                entry_point='warm_probe:main')
            if theirs is not ours and forked is not None and forked.wait(30.0) == 5:
                code = 0
            warm_start._close_zygotes()   # what its exit would do
        finally:
            os._exit(code)
    assert os.waitstatus_to_exitcode(os.waitpid(child, 0)[1]) == 0
    process, _ = start('warm', '0', env, lifeline)
    assert finish(process) == (0, '')
    assert warm_start._zygote_for(env) is ours and ours.usable


def test_a_warm_nodes_cpu_counts_for_the_process_that_started_it(probe_env):
    """os.times() counts only a process's own children; the zygote reports each node's CPU at
    its exit, which is what the suite's per-test CPU (tests/conftest.py) adds."""
    env, lifeline = probe_env
    before = warm_start.finished_children_cpu_s()
    process, _ = start('warm', 'spin', env, lifeline)
    assert finish(process) == (0, '')
    assert warm_start.finished_children_cpu_s() - before >= 0.3   # the probe spins 0.3 s


def test_a_closed_zygotes_nodes_count_once(probe_env):
    """Reaping the zygote adds its waited-for children's CPU to os.times(): the suite's
    per-test CPU must not count the nodes' reports on top (it once charged a test 60.8 s of CPU
    in 5.8 s of wall time, over the 60 s rule)."""
    env, lifeline = probe_env
    env = {**env, 'PYTHONHASHSEED': '11'}   # a zygote of its own
    zygote = warm_start._zygote_for(env)
    for _ in range(5):
        process, _ = start('warm', 'spin', env, lifeline)
        assert finish(process) == (0, '')
    # /proc/<pid>/stat after the name: state is field 3; utime, stime, cutime, cstime 14-17.
    fields = Path(f'/proc/{zygote.process.pid}/stat').read_text().rsplit(')', 1)[1].split()
    tick = os.sysconf('SC_CLK_TCK')
    own_s = (int(fields[11]) + int(fields[12])) / tick
    waited_s = (int(fields[13]) + int(fields[14])) / tick
    assert waited_s >= 1.5   # the five probes' spins

    def counted_s() -> float:
        times = os.times()
        return times.children_user + times.children_system + \
            warm_start.finished_children_cpu_s()

    before = counted_s()
    zygote.close()
    # What reaping it adds is its own CPU, up to its exit (an interpreter's teardown with numpy,
    # numba and OpenCV loaded: 0.3 s measured), not the nodes' again.
    assert own_s <= counted_s() - before < own_s + waited_s / 2
