"""Test-wide settings: DDS stays on loopback and in a domain of this run's own, even when pytest
is started without scripts/test; the tiers; the order tests run in; the time a test may take.

Tests that start whole commands or the node graph as processes are marked ``slow``: every test
under tests/graph/, and modules or tests that say ``pytest.mark.slow``. ``./scripts/test --fast``
(pytest -m 'not slow') runs the rest, the in-process tier a developer runs after every edit.

``./scripts/test`` runs the suite on every core (pytest-xdist): the slow tier first, longest
first, so that the two workers finish together; each worker leases a DDS domain of its own.
A test that uses more than ``TEST_LIMIT_S`` of CPU fails, unless ``LONG_TESTS`` names it with
the reason it needs more: the suite stays quick because nothing grows unseen.
"""

import os
import signal
from pathlib import Path

import pytest
from hypothesis import settings

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('MPLBACKEND', 'Agg')
# A suite started as a background job of a non-interactive shell (`./scripts/test &`, nohup)
# inherits SIGINT ignored, and so would every process it starts: a test that stops a command as
# a terminal's Ctrl-C does found it ignored (a Ctrl-C'd study ran on to its end; a stand-in
# needed SIGTERM). The suite's processes take SIGINT as if started from a terminal.
signal.signal(signal.SIGINT, signal.default_int_handler)

# Property tests draw the same examples every run: a red run is a bug found, never chance.
settings.register_profile('omni_micro', derandomize=True, database=None)
settings.load_profile('omni_micro')

TESTS = Path(__file__).parent
GRAPH_TESTS = TESTS / 'graph'

# The most CPU a single test may use, setup and call, its own process's and every process's it
# started and waited for (the suite's aim: 8 minutes on two cores; a test over a minute is a
# fifteenth of it). CPU, not wall time: the suite is CPU-bound, and CPU is what a test costs
# whatever else runs; on the wall clock two tests went over a minute in a run beside two busy
# processes (the bench's 64.5 s, identify's 60.9 s), a red run by chance. A test that waits on
# the wall clock (the bench at real time) waits as long as its own timeouts let it.
TEST_LIMIT_S = 60.0
# Tests that may take longer, each with why. Measured on this 2-core machine, with the other
# worker busy beside them.
LONG_TESTS: dict[str, str] = {
    'cli/test_simulate_cli.py::test_demo_runs_fig11_through_the_graph':
        "the README's main command end to end, every row it prints checked: the paper's "
        'figures and six graph runs (32 s alone, 50-60 s beside the other worker)',
}
# Tests that take longest, run first so that no worker is left with one at the end (seconds
# each took in a run of the whole suite, both workers busy; the others keep their order).
LONGEST_FIRST: dict[str, float] = {
    'cli/test_simulate_cli.py::test_demo_runs_fig11_through_the_graph': 60,
    'cli/test_study.py::test_ctrl_c_keeps_finished_runs_and_resume_finishes_with_the_same_rows':
        25,
    'graph/test_servo_loop.py::test_on_the_rendered_images_the_servo_reaches_and_records_the_'
    'same_bag_at_any_speed': 30,
    'graph/test_images_loop.py::test_same_seed_same_file_with_images_idle_and_busy_and_no_'
    'frame_lost': 31,
    'graph/test_bench_loop.py::test_the_loop_closes_with_a_standin_camera_and_robot_on_the_'
    'wall_clock_and_a_lab_keeps_its_log': 29,
    'graph/test_servo_loop.py::test_same_seed_same_bag_at_another_speed_busy_and_in_one_'
    'process': 29,
    'graph/test_same_bag.py::test_same_seed_same_file_at_another_real_time_factor': 31,
    'graph/test_captures_in_motion.py::test_same_seed_same_bag_with_late_captures_in_motion_at_'
    'another_speed': 30,
    'graph/test_same_bag.py::test_same_seed_same_file_with_both_cores_kept_busy': 27,
}


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        'markers', 'slow: starts whole commands or the node graph as processes '
                   "(./scripts/test --fast, i.e. -m 'not slow', leaves them out)")
    _lease_a_domain(config)


def _lease_a_domain(config: pytest.Config) -> None:
    """A DDS domain of this pytest process's own (each xdist worker leases one), for the nodes
    tests build in-process: another worker's, or another graph on this machine, is never
    heard. Tests that start graphs lease one more each (tests/graph/conftest.py)."""
    from omni_micro_bringup.processes import DomainLease

    lease = DomainLease()
    os.environ['ROS_DOMAIN_ID'] = str(lease.__enter__())
    config.add_cleanup(lambda: lease.__exit__(None, None, None))


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if GRAPH_TESTS in Path(item.fspath).parents:
            item.add_marker(pytest.mark.slow)
    # The slow tier first, longest first; the quick in-process tests fill the end.
    order = {id(item): index for index, item in enumerate(items)}
    items.sort(key=lambda item: (item.get_closest_marker('slow') is None,
                                 -LONGEST_FIRST.get(_short_id(item), 0.0), order[id(item)]))


def _short_id(item: pytest.Item) -> str:
    """The test's id from the tests folder: ``graph/test_loop.py::test_x[case]``."""
    return item.nodeid.removeprefix('tests/')


_SETUP_S = pytest.StashKey[float]()
_CPU_AT_START = pytest.StashKey[float]()


def cpu_seconds() -> float:
    """CPU this process and its waited-for children (and theirs) have used so far, the nodes it
    started warm (forked by its zygote, which waits for them) included once they exited."""
    from omni_micro_bringup.warm_start import finished_children_cpu_s

    times = os.times()
    return (times.user + times.system + times.children_user + times.children_system
            + finished_children_cpu_s())


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_setup(item: pytest.Item):
    item.stash[_CPU_AT_START] = cpu_seconds()
    yield


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """A test whose setup and call together use over TEST_LIMIT_S of CPU fails, naming it and
    its wall time (a module's shared fixture counts in the first test that sets it up)."""
    outcome = yield
    report = outcome.get_result()
    if report.when == 'setup':
        item.stash[_SETUP_S] = report.duration
    elif report.when == 'call' and report.passed:
        # Less the CPU of busy processes a test ran beside on purpose (busy_machine): the load
        # it asked for, not its cost.
        load = 0.0
        for name, value in item.user_properties:
            if name == 'busy_cpu_s' and isinstance(value, float):
                load += value
        used = cpu_seconds() - item.stash.get(_CPU_AT_START, cpu_seconds()) - load
        took = item.stash.get(_SETUP_S, 0.0) + report.duration
        # In --junitxml's report beside the wall time: what a test costs whatever else runs.
        item.user_properties.append(('cpu_s', round(used, 2)))
        if used > TEST_LIMIT_S and _short_id(item) not in LONG_TESTS:
            report.outcome = 'failed'
            report.longrepr = (f'{_short_id(item)} used {used:.1f} s of CPU ({took:.1f} s of '
                               f'wall time), over the {TEST_LIMIT_S:g} s a test may use: make it '
                               'cheaper, or name it in LONG_TESTS (tests/conftest.py) with its '
                               'reason')


@pytest.fixture
def context():
    """An rclpy context of the test's own, for nodes built in-process (as rclpy's tests do)."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    yield context
    context.try_shutdown()


@pytest.fixture
def no_blas_setting(monkeypatch):
    """The user set nothing (and whatever the test sets is undone afterwards)."""
    monkeypatch.setenv('OPENBLAS_NUM_THREADS', 'unset below')
    monkeypatch.delenv('OPENBLAS_NUM_THREADS')
