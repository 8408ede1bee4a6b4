"""The layouts message templates find, kept on disk (omni_micro_common.template_layouts): read
back, the same bytes; a value changed, a layout of its own; a damaged file or a folder that
cannot be written, the layout found again; and a second process starts without rosbags."""

import os
import subprocess
import sys

import pytest
from nav_msgs.msg import Odometry

from omni_micro_common import cdr
from omni_micro_common.cdr import MessageTemplate, canonical_bytes
from omni_micro_common.template_layouts import layout_folder
from omni_micro_common.tick_messages import ODOMETRY_FIELDS, odometry_template

VALUES = (12, 340_000_000, 0.1, -0.002, 0.38, 0.925, 0.011, -0.0003, 0.5)


@pytest.fixture
def layouts(tmp_path, monkeypatch):
    """A layout folder of this test's own, and how often a layout was found (not read back)."""
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'cache'))
    found = []
    find = cdr._find_layout

    def counted(message, fields):
        found.append(type(message).__name__)
        return find(message, fields)

    monkeypatch.setattr(cdr, '_find_layout', counted)
    return found


def odometry(frame='odom'):
    msg = Odometry()
    msg.header.frame_id, msg.child_frame_id = frame, 'base_link'
    return msg


def with_values(msg):
    (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.pose.pose.position.x,
     msg.pose.pose.position.y, msg.pose.pose.orientation.z, msg.pose.pose.orientation.w,
     msg.twist.twist.linear.x, msg.twist.twist.linear.y, msg.twist.twist.angular.z) = VALUES
    return msg


def test_a_layout_read_back_gives_the_bytes_a_publisher_sends(layouts, tmp_path):
    first = odometry_template()
    assert layouts == ['Odometry'] and len(list(layout_folder().glob('*.json'))) == 1
    assert layout_folder().is_relative_to(tmp_path / 'cache')
    second = odometry_template()
    assert layouts == ['Odometry']   # read back, not found again
    expected = canonical_bytes(with_values(odometry()))
    assert second.encode(VALUES) == first.encode(VALUES) == expected
    assert second.decode(second.encode(VALUES)) == VALUES


def test_a_message_that_differs_in_any_value_has_a_layout_of_its_own(layouts):
    MessageTemplate(odometry(), ODOMETRY_FIELDS)
    MessageTemplate(odometry('map'), ODOMETRY_FIELDS)
    nudged = odometry()
    nudged.pose.covariance[35] = 1e-17   # beyond what numpy prints of an array
    template = MessageTemplate(nudged, ODOMETRY_FIELDS)
    assert layouts == ['Odometry'] * 3
    assert template.encode(VALUES) == canonical_bytes(with_values(nudged))
    fewer = dict(list(ODOMETRY_FIELDS.items())[:2])
    MessageTemplate(odometry(), fewer)
    assert layouts == ['Odometry'] * 4 and len(list(layout_folder().glob('*.json'))) == 4


@pytest.mark.parametrize('damage', ['{"base": "0001', '{"base": "00010000", "offsets": [4]}',
                                    '{"base": "zz", "offsets": []}', ''])
def test_a_damaged_layout_file_is_found_again_and_written_anew(layouts, damage):
    odometry_template()
    (stored,) = layout_folder().glob('*.json')
    whole = stored.read_text()
    stored.write_text(damage)
    template = odometry_template()
    assert layouts == ['Odometry'] * 2
    assert template.encode(VALUES) == canonical_bytes(with_values(odometry()))
    assert stored.read_text() == whole
    assert [path.name for path in layout_folder().iterdir()] == [stored.name]   # nothing aside


def test_a_folder_that_cannot_be_written_costs_only_the_time_to_find_the_layout(
        layouts, tmp_path, monkeypatch):
    monkeypatch.setenv('XDG_CACHE_HOME', str(tmp_path / 'a file'))
    (tmp_path / 'a file').write_text('not a folder')
    for _ in range(2):
        assert odometry_template().encode(VALUES) == canonical_bytes(with_values(odometry()))
    assert layouts == ['Odometry'] * 2


def test_a_second_process_builds_the_robots_templates_without_loading_rosbags(tmp_path):
    script = ('import sys; from omni_micro_common.tick_messages import tick_templates; '
              "tick_templates('odom', 'base_link'); print('rosbags' in sys.modules)")
    env = {**os.environ, 'XDG_CACHE_HOME': str(tmp_path / 'cache')}
    loaded = [subprocess.run([sys.executable, '-c', script], capture_output=True, text=True,
                             check=True, env=env).stdout.strip() for _ in range(2)]
    assert loaded == ['True', 'False']
