"""A Foxglove WebSocket client as a user's Foxglove is one, for the tests of the live view: it
decodes what it gets with the schemas the server advertised, not with any of ours."""

import asyncio
import json
import socket
import struct
import subprocess
import time
from collections.abc import Callable

import websockets
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from websockets.typing import Subprotocol


def wait_for_view(port: int, run: subprocess.Popen) -> None:
    deadline = time.monotonic() + 60
    while True:
        with socket.socket() as sock:
            if sock.connect_ex(('127.0.0.1', port)) == 0:
                return
        assert time.monotonic() < deadline and run.poll() is None, 'no live view'
        time.sleep(0.05)


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(('127.0.0.1', 0))
        return sock.getsockname()[1]


def schema_typestore(schema_name: str, schema: str):
    """Decode with the schema the server advertised, not with any of ours."""
    store = get_typestore(Stores.EMPTY)
    first, *dependencies = schema.split('=' * 80 + '\n')
    types = dict(get_types_from_msg(first, schema_name))
    for dependency in dependencies:
        header, _, body = dependency.partition('\n')
        package, *_, type_name = header.removeprefix('MSG: ').strip().split('/')
        types.update(get_types_from_msg(body, f'{package}/msg/{type_name}'))
    store.register(types)
    return store


async def watch(url: str, seconds: float, enough: Callable[[dict[str, list]], bool],
                 then_slow_s: float) -> dict[str, list]:
    """A Foxglove WebSocket client: subscribe to every channel and decode each message until
    ``enough`` of them came (or ``seconds`` passed, or the server closed); then read slowly,
    5 ms per message, for ``then_slow_s`` (the SDK drops what a slow client cannot take, the
    larger messages first: hence the fast part for what the test checks)."""
    received: dict[str, list] = {}
    async with websockets.connect(url, subprotocols=[Subprotocol('foxglove.sdk.v1')],
                                  max_size=None) as client:
        subscriptions: dict[int, tuple] = {}
        deadline = time.monotonic() + seconds
        slow_until: float | None = None
        while time.monotonic() < (deadline if slow_until is None else slow_until):
            if slow_until is None and enough(received):
                slow_until = time.monotonic() + then_slow_s
            try:
                frame = await asyncio.wait_for(client.recv(), timeout=0.5)
            except TimeoutError:
                continue
            except websockets.ConnectionClosed:
                break
            if isinstance(frame, str):
                message = json.loads(frame)
                if message['op'] == 'serverInfo':
                    assert message['capabilities'] == []     # no publishing, no services
                if message['op'] == 'advertise':
                    wanted = []
                    for channel in message['channels']:
                        assert channel['encoding'] == 'cdr'
                        assert channel['schemaEncoding'] == 'ros2msg'
                        subscription = len(subscriptions) + 1
                        subscriptions[subscription] = (
                            channel['topic'], channel['schemaName'],
                            schema_typestore(channel['schemaName'], channel['schema']))
                        wanted.append({'id': subscription, 'channelId': channel['id']})
                    await client.send(json.dumps({'op': 'subscribe', 'subscriptions': wanted}))
                continue
            opcode, subscription, _ = struct.unpack_from('<BIQ', frame)
            assert opcode == 1
            topic, schema_name, store = subscriptions[subscription]
            received.setdefault(topic, []).append(store.deserialize_cdr(frame[13:], schema_name))
            if slow_until is not None:
                await asyncio.sleep(0.005)    # a viewer that reads slowly
    return received
