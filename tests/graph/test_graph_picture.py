"""`omni-micro graph`: the picture names every topic a run actually carries, with its type, who
publishes and who subscribes, for the plain graph and the one on images."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from omni_micro_tools.bag_reading import read_bag


def graph_json(omni_micro, *flags: str) -> list[dict]:
    done = omni_micro('graph', '--json', *flags)
    assert done.returncode == 0, done.stderr[-3000:]
    return list(json.loads(done.stdout.strip().splitlines()[-1]))


def test_the_picture_names_every_topic_a_recorded_run_carries(omni_micro, fig11_recorded):
    bag, _ = fig11_recorded
    carried = read_bag(bag, decode=False)
    described = {topic['topic']: topic for topic in graph_json(omni_micro, '--record')}
    for name, msgtype in carried.msgtypes.items():
        if carried.raw[name]:
            assert name in described, f'{name} is carried by a run but not in the picture'
            assert described[name]['msgtype'] == msgtype
            assert described[name]['publishers'], f'{name}: no publisher drawn'
    assert {'dynamics_node'} == {p['node'] for p in described['/odom']['publishers']}
    assert 'vision_node' in {s['node'] for s in described['/odom']['subscribers']}
    assert 'dynamics_node' in {s['node'] for s in described['/lockstep']['subscribers']}
    assert 'bag_recorder' in {s['node'] for s in described['/odom']['subscribers']}


def test_the_picture_of_the_graph_on_images_has_the_camera_streams(omni_micro, tmp_path):
    described = {t['topic']: t for t in graph_json(omni_micro, '--vision', 'images',
                                                   '--no-markers')}
    assert described['/camera/macro/image_raw']['msgtype'] == 'sensor_msgs/msg/Image'
    assert {p['node'] for p in described['/camera/micro/image_raw']['publishers']} == {
        'camera_node'}
    assert 'tracker_node' in {s['node'] for s in described['/camera/micro/image_raw'][
        'subscribers']}
    assert '/markers' not in described


@pytest.fixture(scope='module')
def plain_picture(tmp_path_factory, omni_micro) -> tuple[Path, list[dict]]:
    """One bring-up of the plain graph: its picture and the same as JSON."""
    out = tmp_path_factory.mktemp('picture') / 'graph.svg'
    done = omni_micro('graph', '--out', str(out), '--json')
    assert done.returncode == 0, done.stderr[-3000:]
    return out, list(json.loads(done.stdout.strip().splitlines()[-1]))


def test_the_picture_is_written_whole_and_readable_by_others(plain_picture):
    out, topics = plain_picture
    assert [p.name for p in out.parent.iterdir()] == [out.name]
    assert out.stat().st_mode & 0o044, 'written private (0600): others cannot read it'
    text = out.read_text()
    assert text.startswith('<?xml') and '<svg' in text and len(text) > 20_000
    for topic in topics:
        assert f'>{topic["topic"]}' in text


def test_the_picture_the_readme_shows_is_the_graph_of_today(plain_picture):
    """docs/figures/graph.svg (README, the docs) names every topic and node a plain run's graph
    has: regenerate it with `omni-micro graph --out docs/figures/graph.svg` when this fails."""
    _, topics = plain_picture
    shown = (Path(__file__).resolve().parents[2] / 'docs' / 'figures' / 'graph.svg').read_text()
    for topic in topics:
        assert f'>{topic["topic"]}' in shown, f'{topic["topic"]} is not in the picture'
        for endpoint in (*topic['publishers'], *topic['subscribers']):
            if endpoint['node'] != 'omni_micro_orchestration':
                assert endpoint['node'] in shown, endpoint['node']


def test_the_picture_of_several_robots_names_each_robot_s_nodes_under_its_namespace(
        omni_micro):
    """`graph --robots 2`: the fleet's graph as `run --robots 2` brings it up, one
    dynamics_node for both robots and each robot's own nodes and topics under /robot_k, told
    apart by their namespace (the single robot's keep their bare names), and no topic of the
    root namespace's robot, which a fleet has not."""
    described = {t['topic']: t for t in graph_json(omni_micro, '--robots', '2')}
    for k in range(2):
        assert {p['node'] for p in described[f'/robot_{k}/odom']['publishers']} == {
            'dynamics_node'}
        assert {s['node'] for s in described[f'/robot_{k}/goal_pose']['subscribers']} == {
            f'robot_{k}/controller_node', f'robot_{k}/markers_node'}
        assert {p['node'] for p in described[f'/robot_{k}/camera/macro/pose']['publishers']} \
            == {f'robot_{k}/vision_node'}
    assert {p['node'] for p in described['/robot_contacts']['publishers']} == {'dynamics_node'}
    # The orchestration follows each robot on its own topics: none of a single robot's.
    assert not {'/goal_pose', '/controller/status', '/camera/status', '/odom_throttle'} & set(
        described)
    refused = omni_micro('graph', '--json', '--robots', '0')
    assert refused.returncode == 2 and refused.stderr.strip() == (
        "omni-micro graph: error: --robots must be a whole number 1..42 or a YAML file, got '0'")
