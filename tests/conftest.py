"""Test-wide settings: DDS stays on loopback even when pytest is started without scripts/test."""

import os
from pathlib import Path

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(
    Path(__file__).resolve().parents[1] / 'ros2_ws/src/omni_micro_sim/config/fastdds.xml'))
os.environ.setdefault('MPLBACKEND', 'Agg')
