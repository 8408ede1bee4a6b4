"""Running a study's runs on Dask (or in a plain loop), keeping every finished run on disk;
and any other scenario's runs (compare-controllers' cases, fleet-study's fleets) on the same
cluster or scheduler (:func:`map_on_dask`).

A study directory holds ``study.yaml`` (the file as given) from the start, finished runs in
``parts/`` as they come (each part written whole: a temporary file, then a rename), and, once
every run is done, ``runs.parquet`` with one row per run in run order. An interrupted study
(Ctrl-C, a killed process, a lost scheduler) keeps its parts; ``--resume`` runs only what is
missing. A worker that dies takes only its unfinished runs with it: Dask's scheduler gives
those to another worker.
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from omni_micro_studies.errors import StudyError
from omni_micro_studies.runs import run_rows, warm_up
from omni_micro_studies.spec import Study, load_study

STUDY_FILE = 'study.yaml'
RUNS_FILE = 'runs.parquet'
PARTS_DIR = 'parts'
# Closed-loop runs take ~0.05-0.15 s: one per task, so that a dead worker loses one run. An
# open-loop move takes ~1 ms: batched, or the scheduler's ~1 ms per task would dominate.
RUNS_PER_TASK = {'closed_loop': 1, 'open_loop': 25}
CHECKPOINT_INTERVAL_S = 2.0


def schema(study: Study) -> pa.Schema:
    """Every row's columns and types: inputs, seed, metrics, wall time, error."""
    fields = [pa.field(name, pa.int64()) for name in ('run', 'point', 'replicate')]
    fields += [pa.field('mode', pa.string()), pa.field('seed', pa.int64()),
               pa.field('steering', pa.string())]
    fields += [pa.field(name, pa.float64()) for name in study.parameters]
    for column in study.metric_columns:
        kind = {'outcome': pa.string(), 'periods': pa.int64()}.get(column, pa.float64())
        fields.append(pa.field(column, kind))
    fields += [pa.field('wall_s', pa.float64()), pa.field('error', pa.string())]
    return pa.schema(fields)


def to_table(study: Study, rows: list[dict[str, Any]]) -> pa.Table:
    names = schema(study).names
    return pa.Table.from_pylist([{name: row.get(name) for name in names} for row in rows],
                                schema=schema(study))


def _write_whole(table: pa.Table, target: Path) -> None:
    handle, temporary = tempfile.mkstemp(prefix=f'.{target.name}.partial-', dir=target.parent)
    os.close(handle)
    try:
        pq.write_table(table, temporary)
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


class Checkpoint:
    """Finished rows, flushed to a new part file every few seconds and at the end."""

    def __init__(self, study: Study, directory: Path) -> None:
        self.study = study
        self.directory = directory
        self.pending: list[dict[str, Any]] = []
        self.flushed_at = time.monotonic()
        self.kept = 0

    def add(self, rows: list[dict[str, Any]]) -> None:
        self.pending.extend(rows)
        if time.monotonic() - self.flushed_at >= CHECKPOINT_INTERVAL_S:
            self.flush()

    def flush(self) -> None:
        self.flushed_at = time.monotonic()
        if not self.pending:
            return
        self.directory.mkdir(exist_ok=True)
        first = min(row['run'] for row in self.pending)
        name = f'part-{time.time_ns():020d}-{first:08d}.parquet'
        _write_whole(to_table(self.study, self.pending), self.directory / name)
        self.kept += len(self.pending)
        self.pending = []


def _read_rows(path: Path, study: Study | None = None) -> list[dict[str, Any]]:
    """A parquet file's rows; a file that is not one (damaged, emptied, another schema) is a
    StudyError naming it."""
    try:
        return list(pq.read_table(path, schema=None if study is None else schema(study))
                    .to_pylist())
    except (pa.ArrowException, OSError, ValueError) as error:
        reason = (str(error).strip().splitlines() or [type(error).__name__])[0]
        raise StudyError(f'{path}: not a readable table of rows ({reason}); move it away and '
                         'the runs it held run again with --resume') from None


def finished_rows(study: Study, out: Path) -> list[dict[str, Any]]:
    """The rows kept so far (from runs.parquet, or the parts of an unfinished study)."""
    if (out / RUNS_FILE).exists():
        return _read_rows(out / RUNS_FILE)
    rows: dict[int, dict[str, Any]] = {}
    for part in sorted((out / PARTS_DIR).glob('part-*.parquet')):
        for row in _read_rows(part, study):
            rows.setdefault(row['run'], row)
    return list(rows.values())


def load_directory(out: Path) -> Study:
    """The study a results directory was made for."""
    if not (out / STUDY_FILE).exists():
        raise StudyError(f'{out}: not a study directory (no {STUDY_FILE})')
    return load_study(out / STUDY_FILE)


def forget_directory(out: Path, created: bool) -> None:
    """Undo ``prepare_directory`` for a study that ran nothing: no study.yaml is left behind
    (and the folder itself goes if it was made for the study)."""
    (out / STUDY_FILE).unlink(missing_ok=True)
    with contextlib.suppress(OSError):
        (out / PARTS_DIR).rmdir()
    if created:
        with contextlib.suppress(OSError):
            out.rmdir()


def prepare_directory(study: Study, out: Path) -> None:
    """Create ``out`` for a new study; refuse one that holds another."""
    if (out / STUDY_FILE).exists():
        state = 'a finished' if (out / RUNS_FILE).exists() else 'an unfinished'
        hint = ('choose another --out' if state == 'a finished'
                else f'finish it with --resume {out}, or choose another --out')
        raise StudyError(f'--out {out}: already holds {state} study; {hint}')
    if out.exists() and any(out.iterdir()):
        raise StudyError(f'--out {out}: exists and is not empty; choose a new directory')
    out.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f'.{STUDY_FILE}.partial-', dir=out)
    with os.fdopen(handle, 'w') as stream:
        stream.write(study.text)
    os.replace(temporary, out / STUDY_FILE)


@dataclass
class Execution:
    total: int
    already_done: int
    ran: int
    wall_s: float           # all of it, starting the cluster included
    compute_s: float        # from warm workers to the last run
    where: str


@contextlib.contextmanager
def dask_client(workers: int, scheduler: str | None,
                scheduler_timeout_s: float = 10.0) -> Iterator[Any]:
    """A client of ``scheduler``, or of a LocalCluster of ``workers`` processes on loopback."""
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=scheduler_timeout_s)
        except OSError as error:
            raise StudyError(f'--scheduler {scheduler}: cannot connect ({error})') from None
        with client:
            yield client
        return
    # One single-threaded worker process per core: the runs are pure Python and numba, which
    # threads would serialise on the GIL. Loopback only, no dashboard.
    # Ctrl-C is for this process, which stops the cluster: started with SIGINT ignored, the
    # worker processes inherit that (Python keeps an inherited SIG_IGN), so a terminal's Ctrl-C
    # to the whole group does not end each of them with a KeyboardInterrupt traceback.
    # Its workers log nothing below CRITICAL: what a run raises reaches this process through
    # its future, and a worker's death through the cluster (both tested). The ERROR lines they
    # printed were the shutdown's race, a heartbeat to a scheduler already closed, with two
    # tracebacks after a Ctrl-C (once in CI).
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               host='127.0.0.1', dashboard_address=None,
                               silence_logs=logging.CRITICAL)
    finally:
        signal.signal(signal.SIGINT, previous)
    with cluster, Client(cluster) as client:
        yield client


def local_workers(workers: int) -> int:
    """The local cluster's size: ``workers``, or one per core for 0."""
    return workers or os.cpu_count() or 1


def runs_go_to(workers: int, scheduler: str | None) -> str:
    """Where :func:`map_on_dask` sends its tasks, as a command says it."""
    return (f'the scheduler {scheduler}' if scheduler else
            f'a local Dask cluster of {local_workers(workers)} processes')


def map_on_dask(function: Callable[..., Any], tasks: Sequence[tuple[Any, ...]], *,
                workers: int = 0, scheduler: str | None = None,
                scheduler_timeout_s: float = 10.0,
                on_result: Callable[[int, Any], None] | None = None) -> list[Any]:
    """``function(*task)`` for every task, on a local cluster of ``workers`` processes (0: one
    per core) or on ``scheduler``'s workers; the results in the tasks' order, whatever order
    they finish in. ``on_result(done, result)`` is called as each arrives (progress).

    Raises
    ------
    StudyError
        ``scheduler`` cannot be reached.
    """
    from distributed import as_completed

    results: list[Any] = [None] * len(tasks)
    if not tasks:
        return results
    with dask_client(local_workers(workers), scheduler, scheduler_timeout_s) as client:
        futures = {client.submit(function, *task, pure=False): index
                   for index, task in enumerate(tasks)}
        try:
            for done, future in enumerate(as_completed(futures), start=1):
                results[futures[future]] = future.result()
                if on_result is not None:
                    on_result(done, results[futures[future]])
        finally:
            client.cancel(list(futures))
    return results


def _tasks(study: Study, rows: list[dict[str, Any]]) -> list[list[dict[str, Any]]]:
    size = RUNS_PER_TASK[study.scenario]
    return [rows[i:i + size] for i in range(0, len(rows), size)]


def execute(study: Study, out: Path, *, workers: int, scheduler: str | None = None,
            scheduler_timeout_s: float = 10.0, serial: bool = False,
            progress: bool = True) -> Execution:
    """Run every run of ``study`` not yet kept in ``out``; keep each as it finishes.

    On KeyboardInterrupt the finished runs are on disk before it propagates.
    """
    from tqdm import tqdm

    done = {row['run'] for row in finished_rows(study, out)}
    todo = [row for row in study.runs() if row['run'] not in done]
    columns = study.metric_columns
    began = time.perf_counter()
    checkpoint = Checkpoint(study, out / PARTS_DIR)
    bar = tqdm(total=study.run_count, initial=len(done), unit='run', desc=study.name,
               file=sys.stderr, mininterval=0.5, disable=not progress, dynamic_ncols=True)
    where = 'this process (serial)'
    computing = time.perf_counter()
    try:
        if not todo:
            where = 'nothing left to run'
        elif serial:
            warm_up()
            computing = time.perf_counter()
            for task in _tasks(study, todo):
                finished = run_rows(task, columns)
                checkpoint.add(finished)
                bar.update(len(finished))
        else:
            from distributed import as_completed

            with dask_client(workers, scheduler, scheduler_timeout_s) as client:
                where = (f'scheduler {scheduler}' if scheduler else
                         f'LocalCluster of {workers} worker processes')
                client.run(warm_up)
                computing = time.perf_counter()
                futures = [client.submit(run_rows, task, columns, pure=False)
                           for task in _tasks(study, todo)]
                try:
                    for future in as_completed(futures):
                        finished = future.result()
                        checkpoint.add(finished)
                        bar.update(len(finished))
                finally:
                    client.cancel(futures)
    finally:
        checkpoint.flush()
        bar.close()
    finished_at = time.perf_counter()
    return Execution(study.run_count, len(done), len(todo), finished_at - began,
                     finished_at - computing, where)


def collect(study: Study, out: Path) -> pa.Table:
    """Every run's row in run order, written to runs.parquet; the parts are then removed."""
    rows = sorted(finished_rows(study, out), key=lambda row: row['run'])
    if len(rows) != study.run_count:
        raise StudyError(f'{out}: {len(rows)} of {study.run_count} runs kept; --resume {out}')
    table = to_table(study, rows)
    _write_whole(table, out / RUNS_FILE)
    for part in (out / PARTS_DIR).glob('*'):
        part.unlink()
    with contextlib.suppress(FileNotFoundError):
        (out / PARTS_DIR).rmdir()
    return table

