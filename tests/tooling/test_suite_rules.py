"""The suite's own rules (tests/conftest.py), checked on a suite of a few tests: a test over the
CPU limit fails unless named with its reason, a test that only waits does not, nor one whose
busy processes (busy_machine) burn it; the slow tier runs first, longest first; property tests
draw the same examples every run."""

from pathlib import Path

CONFTEST = (Path(__file__).resolve().parents[1] / 'conftest.py').read_text()


def a_suite(pytester, limit_s: float, long_tests: str = '{}', longest: str = '{}') -> None:
    """The suite's conftest with its limit and lists set for the few tests below (the hooks
    read them when they run)."""
    pytester.makeconftest(CONFTEST + f'\nTEST_LIMIT_S = {limit_s}\nLONG_TESTS = {long_tests}\n'
                                     f'LONGEST_FIRST = {longest}\n')
    pytester.makepyfile(test_timing='''
import os
import subprocess
import sys
import time

import pytest


def burn(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_quick():
    time.sleep(0.5)   # waits, uses no CPU


def test_slow_and_named():
    burn(0.4)


def test_slow_and_not_named():
    # Under the limit in this process, over it with the process it starts and waits for.
    burn(0.2)
    subprocess.run([sys.executable, '-c', 'import time\\nend = time.process_time() + 0.25'
                    '\\nwhile time.process_time() < end: pass'], check=True)


def cpu_s(pid):
    fields = open(f'/proc/{pid}/stat').read().rsplit(')', 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf('SC_CLK_TCK')


def test_beside_busy_processes(request):
    # The busy process burns 0.4 s or more, over the limit: the load asked for, not this
    # test's. (Waited for by its own CPU: on a loaded machine it gets less than a core.)
    from omni_micro_bringup.machine_load import busy_cores

    def note(used_s):
        request.node.user_properties.append(('busy_cpu_s', used_s))
    with busy_cores(1, on_done=note) as (hog,):
        deadline = time.monotonic() + 120
        while cpu_s(hog.pid) < 0.4 and time.monotonic() < deadline:
            time.sleep(0.05)
    assert request.node.user_properties[-1][1] > 0.3


@pytest.mark.slow
def test_marked_slow():
    pass


@pytest.mark.slow
def test_marked_slow_and_longest():
    pass
''')


def test_a_test_over_the_limit_fails_unless_it_is_named_with_its_reason(pytester):
    a_suite(pytester, 0.3, long_tests="{'test_timing.py::test_slow_and_named': 'sleeps'}")
    result = pytester.runpytest('-p', 'no:cacheprovider')
    result.assert_outcomes(passed=5, failed=1)
    # Its own 0.2 s alone would pass: the process it waited for counts too.
    result.stdout.fnmatch_lines(['*test_timing.py::test_slow_and_not_named used * s of CPU '
                                 '(* s of wall time), over the 0.3 s a test may use*'])


def test_the_slow_tier_runs_first_and_the_longest_of_it_first(pytester):
    a_suite(pytester, 60.0, longest="{'test_timing.py::test_marked_slow_and_longest': 30.0}")
    result = pytester.runpytest('-p', 'no:cacheprovider', '--collect-only', '-q')
    names = [line.split('::')[-1] for line in result.outlines if '::' in line]
    assert names == ['test_marked_slow_and_longest', 'test_marked_slow', 'test_quick',
                     'test_slow_and_named', 'test_slow_and_not_named',
                     'test_beside_busy_processes']


def test_property_tests_draw_the_same_examples_every_run():
    from hypothesis import settings

    current = settings.default
    assert current is not None and current.derandomize and current.database is None
