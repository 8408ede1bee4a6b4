"""What Fast DDS itself says goes to standard error: a command's ``--json`` stays the whole of
standard output when the middleware complains (a suite run once printed Fast DDS's
``RTPS_TRANSPORT_SHM Error: Failed init_port`` ahead of a bench-fleet run's JSON)."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
from collections.abc import Iterator

from omni_micro_bringup.shared_memory import SHM

# RTPS's port mapping (DDSI-RTPS 9.6.1.1, Fast DDS's defaults): a participant's user-traffic
# unicast port is PB + DG * domain + d3 + PG * participant; Fast DDS's shared-memory transport
# names its port files after it. 60 participants stay below the next domain's ports.
PB, DG, PG, D3 = 7400, 250, 2, 11


@contextlib.contextmanager
def shared_memory_ports_locked(domain_id: int, participants: int = 60) -> Iterator[None]:
    """Every shared-memory port of the domain's participants locked by another process, as a
    participant that still holds its port's lock file leaves it (Fast DDS locks
    ``fastrtps_port<N>_el`` with flock): each participant of the domain then fails to open one,
    says so, and goes on over UDP."""
    ports = [f'fastrtps_port{PB + DG * domain_id + D3 + PG * k}' for k in range(participants)]
    locks = []
    try:
        for port in ports:
            lock = os.open(SHM / f'{port}_el', os.O_CREAT | os.O_RDONLY, 0o666)
            locks.append(lock)
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        yield
    finally:
        for lock in locks:
            os.close(lock)
        for port in ports:   # the domain is this test's lease: no one else's files
            for name in (port, f'{port}_el', f'sem.{port}_mutex'):
                (SHM / name).unlink(missing_ok=True)


def test_fast_dds_errors_go_to_standard_error_and_json_stays_the_whole_output(
        omni_micro, domain_id):
    env = dict(os.environ)
    env.pop('FASTRTPS_DEFAULT_PROFILES_FILE', None)   # a lab's shell that exported nothing
    with shared_memory_ports_locked(domain_id):
        done = omni_micro('preflight', '--robots', '0', '--duration', '1', '--domain-id',
                          str(domain_id), '--json', env=env)
    assert 'Failed init_port fastrtps_port' in done.stderr, done.stderr   # it did complain
    report = json.loads(done.stdout)   # the whole of it: one document, nothing around it
    assert report['cameras'] and all(camera['frames'] == 0 for camera in report['cameras'])
    assert done.returncode == 1   # no camera is running: that needs action
