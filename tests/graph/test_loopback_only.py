"""No DDS traffic leaves loopback: every RTPS datagram sent while a graph runs, captured on
every interface of the machine, goes from 127.0.0.1 to 127.0.0.1 on ``lo``.

Looked at where the datagrams go, not at the sockets: rmw_fastrtps, under
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, adds a UDP transport of its own beside the
profile's loopback one, which binds sockets to the machine's other addresses and announces
them among each participant's locators (docs/reliability.md); what matters is that nothing is
ever sent there, nor to a multicast group."""

from __future__ import annotations

import ipaddress
import json
import socket
import threading
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager

import pytest

ETH_P_ALL = 0x0003
ETH_P_IP = 0x0800
IPPROTO_UDP = 17


@contextmanager
def rtps_datagrams() -> Iterator[Counter[tuple[str, str, str]]]:
    """Counts the RTPS datagrams over UDP/IPv4 seen on any interface while the block runs, by
    (interface, source, destination)."""
    try:
        capture = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    except PermissionError:
        pytest.skip('capturing packets needs CAP_NET_RAW (root)')
    capture.settimeout(0.1)
    seen: Counter[tuple[str, str, str]] = Counter()
    stop = threading.Event()

    def read() -> None:
        while not stop.is_set():
            try:
                frame, (interface, *_) = capture.recvfrom(65535)
            except TimeoutError:
                continue
            if int.from_bytes(frame[12:14], 'big') != ETH_P_IP:
                continue
            ip = frame[14:]
            if ip[9] != IPPROTO_UDP:
                continue
            header = (ip[0] & 0x0F) * 4
            if ip[header + 8:header + 12] == b'RTPS':
                seen[(interface, socket.inet_ntoa(ip[12:16]), socket.inet_ntoa(ip[16:20]))] += 1

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        yield seen
    finally:
        stop.set()
        reader.join()
        capture.close()


def test_every_rtps_datagram_of_a_run_stays_on_loopback(omni_micro):
    with rtps_datagrams() as seen:
        done = omni_micro('run', '--goal-mm', '100,0', '--rtf', 'max', '--seed', '1', '--json',
                          '--quiet')
    assert 'outcome' in json.loads(done.stdout), done.stderr   # the run ran
    # The capture works: a graph's discovery and data are hundreds of datagrams.
    assert sum(seen.values()) > 100, seen
    astray = {key: count for key, count in seen.items()
              if key[0] != 'lo' or not all(ipaddress.ip_address(address).is_loopback
                                           for address in key[1:])}
    assert not astray, f'RTPS datagrams off loopback: {astray}'
