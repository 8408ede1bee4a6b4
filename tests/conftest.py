"""Test-wide settings: DDS stays on loopback even when pytest is started without scripts/test;
the tiers.

Tests that start whole commands or the node graph as processes are marked ``slow``: every test
under tests/graph/, and modules or tests that say ``pytest.mark.slow``. ``./scripts/test --fast``
(pytest -m 'not slow') runs the rest, the in-process tier a developer runs after every edit.
"""

import os
from pathlib import Path

import pytest

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('MPLBACKEND', 'Agg')

GRAPH_TESTS = Path(__file__).parent / 'graph'


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        'markers', 'slow: starts whole commands or the node graph as processes '
                   "(./scripts/test --fast, i.e. -m 'not slow', leaves them out)")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if GRAPH_TESTS in Path(item.fspath).parents:
            item.add_marker(pytest.mark.slow)


@pytest.fixture
def context():
    """An rclpy context of the test's own, for nodes built in-process (as rclpy's tests do)."""
    import rclpy
    from rclpy.context import Context

    context = Context()
    rclpy.init(context=context)
    yield context
    context.try_shutdown()
