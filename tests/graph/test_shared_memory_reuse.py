"""What Fast DDS leaves in /dev/shm when a node stops on its signal (nothing) and when a writer
is killed, and what the graph's cleaning does with that (omni_micro_bringup.shared_memory;
docs/development.md, "The suite")."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

from conftest import Probe
from rcl_interfaces.srv import GetParameters
from std_msgs.msg import String

from omni_micro_bringup.processes import node_environment
from omni_micro_bringup.shared_memory import (
    SHM,
    clean_shared_memory,
    shared_memory_files,
    shared_memory_files_in_use,
    shared_memory_holders,
    shared_memory_identities,
)

WRITER = textwrap.dedent('''
    import time, rclpy
    from rclpy.context import Context
    from rclpy.node import Node
    from std_msgs.msg import String
    context = Context()
    rclpy.init(context=context)
    node = Node('killed_writer', context=context)
    publisher = node.create_publisher(String, 'chatter', 10)
    while True:
        publisher.publish(String(data='still here'))
        time.sleep(0.01)
''')


def test_a_readers_port_outlives_it_when_its_writer_was_killed_and_is_cleaned(
        domain_id, tmp_path: Path, shared_memory_audited_alone):
    """A port counts the processes that opened it and the last to close it removes it: the
    killed writer never closes the reader's port, so the reader's normal exit leaves it, with no
    lock file and mapped by nobody. The next participant of any domain takes it as it is (the
    same file; in one suite run the other worker's did, at once) and leaves it in turn; the
    graph's cleaning removes it, or names the process that took it."""
    reader = Probe(domain_id)
    received: list[String] = []
    reader.node.create_subscription(String, 'chatter', received.append, 10)
    writer = subprocess.Popen([sys.executable, '-c', WRITER],
                              env=node_environment(domain_id, tmp_path))
    try:
        reader.spin_until(lambda: len(received) >= 5, 20.0, "the writer's messages")
        # The reader's own ports: those whose lock file it holds.
        listened = {name.removesuffix('_el') for name in shared_memory_files_in_use([os.getpid()])
                    if name.startswith('fastrtps_port') and name.endswith('_el')}
        opened_by_both = shared_memory_identities(
            listened & set(shared_memory_holders([writer.pid])))
        assert opened_by_both, 'the writer opened none of the reader\'s ports'
    finally:
        writer.send_signal(signal.SIGKILL)
        writer.wait()
    reader.close()
    left = shared_memory_identities({name for name, _ in opened_by_both}) & opened_by_both
    assert left == opened_by_both
    # Another participant (the suite's other worker starts them all the time) may take such a
    # port at once, as it is: then it holds it, with a lock file of its own, which it holds
    # before it maps the port (a run caught one between the two).
    holders = shared_memory_holders()
    for name, _ in left:
        assert {name, f'{name}_el'} & set(holders) or not (SHM / f'{name}_el').exists()
    taken = clean_shared_memory(left, graph_pids=[])
    assert all(pids and os.getpid() not in pids for pids in taken.values())
    # Every one no other process took is gone.
    still_there = shared_memory_identities({name for name, _ in left}) & left
    assert {name for name, _ in still_there} <= set(taken)


def test_a_node_stopped_by_its_signal_leaves_nothing_in_shared_memory(
        start_node, probe, shared_memory_audited_alone):
    """Every node process ends with a fast exit (omni_micro_common.node_runtime): its DDS
    participant must be gone by then, or each run of the graph leaves each node's segment and
    ports in /dev/shm for good. They did, once the executor had spun: 0.5 MB a node, 4.4 MB
    with the graph's profile, every run (a node stopped within its first second left none)."""
    # A port a killed process left is taken as it is and left again (the test above): only
    # the files this node made are its to remove.
    there_before = shared_memory_identities(shared_memory_files())
    node = start_node('omni_micro_vision', 'vision_node')
    # It answers a service: its executor spins.
    client = probe.node.create_client(GetParameters, '/vision_node/get_parameters')
    assert probe.call(client, GetParameters.Request(names=['seed']), timeout_s=30.0).values
    made = shared_memory_identities(set(shared_memory_holders([node.pid]))) - there_before
    # Its own segment (fastrtps_<hex>), made with its participant.
    assert any(not name.startswith('fastrtps_port') for name, _ in made)
    node.send_signal(signal.SIGINT)
    assert node.wait(20) == 0
    # Left: the same files (by inode) that no living process holds; a port another
    # participant opened too (this probe, the other worker's) is theirs to close.
    holders = shared_memory_holders()
    left = {name for name, _ in shared_memory_identities({name for name, _ in made}) & made
            if name not in holders}
    assert not left
