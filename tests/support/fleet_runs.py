"""A micro-factory run from a robots file and a tasks file through the graph, as the docs show
it (`run --robots FILE --tasks FILE`), and the check that two such runs are the same."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path


def run_fleet_files(omni_micro: Callable, folder: Path, robots: str, tasks: str,
                    *arguments: str) -> dict:
    """``robots`` and ``tasks`` (YAML) written into ``folder`` and run with ``arguments``, the
    bag recorded into ``folder/bag`` and the logs into ``folder/logs``: the run's JSON."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / 'robots.yaml').write_text(robots)
    (folder / 'tasks.yaml').write_text(tasks)
    done = omni_micro('run', '--robots', str(folder / 'robots.yaml'), '--tasks',
                      str(folder / 'tasks.yaml'), '--log-dir', str(folder / 'logs'),
                      '--record', str(folder / 'bag'), '--json', *arguments)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


def assert_same_run_and_bag(reference: Path, other: Path, other_summary: dict) -> None:
    """The same JSON as ``reference/summary.json`` but its wall times, and the same bag file,
    byte for byte."""
    first = json.loads((reference / 'summary.json').read_text())
    second = dict(other_summary)
    for summary in (first, second):
        del summary['wall_s'], summary['planning_s'], summary['running_wall_s']
    assert second == first
    assert_same_bag_file(reference / 'bag', other / 'bag')


def assert_same_bag_file(reference: Path, other: Path) -> None:
    """The same bag file, byte for byte; if not, the first message where they part is named
    (one number in a status once told a race apart from a lost message)."""
    (recorded,) = reference.glob('*.mcap')
    written = other / recorded.name
    if written.read_bytes() != recorded.read_bytes():
        raise AssertionError(f'{written} is not {recorded}: {first_difference(recorded, written)}')


def first_difference(reference: Path, other: Path) -> str:
    """Where two MCAP files' messages first part, in stored order: topic, index, log time."""
    from mcap.reader import make_reader

    def messages(path: Path) -> list[tuple[str, int, bytes]]:
        with open(path, 'rb') as stream:
            return [(channel.topic, message.log_time, message.data) for _, channel, message
                    in make_reader(stream).iter_messages(log_time_order=False)]

    first, second = messages(reference), messages(other)
    for index, (a, b) in enumerate(zip(first, second, strict=False)):
        if a != b:
            part = 'its bytes' if a[:2] == b[:2] else f'{b[0]} at {b[1]} ns'
            return f'message {index} ({a[0]} at {a[1]} ns) differs: {part}'
    if len(first) != len(second):
        return f'{len(first)} messages against {len(second)}'
    return 'the same messages, stored otherwise (metadata, chunks, index)'
