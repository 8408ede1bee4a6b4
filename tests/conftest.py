"""Test-wide settings: DDS stays on loopback even when pytest is started without scripts/test."""

import os

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('MPLBACKEND', 'Agg')
