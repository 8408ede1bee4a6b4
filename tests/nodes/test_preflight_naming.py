"""The preflight names the robots of several in a camera's frame as tracker_node would (by
their codes, through the tracker's geometry), and says of each robot no camera named why."""

import numpy as np
from rclpy.serialization import serialize_message
from sensor_msgs.msg import Image

from omni_micro_bringup.preflight import CameraWatch, naming_findings
from omni_micro_bringup.preflight_probe import _named
from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.rendering import InView, Sensor, render_robots
from omni_micro_vision.tracked_camera import tracked_camera


def nominal(name: str, default: object) -> object:
    """A tracker's setting as its params leave it: the default (the nominal macro camera)."""
    return default


def test_robots_in_a_frame_are_named_by_their_codes_and_the_others_said():
    robots = [InView(RobotState(0.03, 0.01, 0.4), 0), InView(RobotState(0.07, -0.02, 2.0), 1),
              InView(RobotState(0.05, 0.04, -1.0), None)]
    pixels = render_robots(DEFAULT_RIG.macro, Sensor(), robots, np.random.default_rng(3))
    rows, columns = pixels.shape
    data = bytes(serialize_message(Image(height=rows, width=columns, encoding='mono8',
                                         step=columns, data=pixels.tobytes())))
    names = ['robot_0', 'robot_1', 'robot_2']
    named = _named(data, tracked_camera('macro', nominal), names)
    assert named['robot_0'] == named['robot_1'] == 'named'
    assert named['robot_2'] != 'named' and named['robot_2']   # why: the uncoded robot's reason
    macro = CameraWatch('macro', '/camera/macro/image_raw', '/camera/macro/camera_info')
    macro.named = named
    (said,) = naming_findings(names, [macro])
    assert said == (f'robot_2: named by no camera (macro: {named["robot_2"]}): check its code '
                    'and that it is in a field')
    # A frame of another size is refused, as the tracker refuses it, for every robot.
    small = bytes(serialize_message(Image(height=4, width=4, encoding='mono8', step=4,
                                          data=bytes(16))))
    refused = _named(small, tracked_camera('macro', nominal), names)
    assert all(reason.startswith('frame refused: ') for reason in refused.values())
