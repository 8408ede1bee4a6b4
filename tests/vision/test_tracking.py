"""From per-frame poses to captures (omni_micro_vision.tracking): still only when the last
frames agree, and only the finest camera that sees the robot speaks, decided by stamps alone
whatever order the cameras' frames arrive in."""

import itertools

from omni_micro_vision.tracking import CameraArbiter, StillnessRule

UM = 1e-6


def test_still_once_the_last_frames_agree_within_the_tolerance():
    rule = StillnessRule(3, 1 * UM)
    assert not rule.still(0.0, 0.0)
    assert not rule.still(0.5 * UM, 0.0)          # only two frames so far
    assert rule.still(0.2 * UM, 0.0)
    assert not rule.still(5 * UM, 0.0)            # moved
    assert not rule.still(5 * UM, 0.0)
    assert rule.still(5.4 * UM, 0.3 * UM)
    rule.reset()                                   # a frame without the robot
    assert not rule.still(5.4 * UM, 0.3 * UM)


FRAMES = [  # (camera, stamp, robot found, capture)
    ('macro', 100, True, 'macro@100'), ('micro', 100, False, None),
    ('macro', 133, True, 'macro@133'), ('micro', 133, True, None),    # micro sees, moving
    ('macro', 167, True, 'macro@167'), ('micro', 167, True, 'micro@167'),
]


def test_the_finest_camera_that_sees_the_robot_speaks_in_any_arrival_order():
    outcomes = set()
    for macro_first in itertools.product([True, False], repeat=3):
        arbiter: CameraArbiter[str] = CameraArbiter(['micro', 'macro'])
        published = []
        for pair, first in zip(zip(FRAMES[::2], FRAMES[1::2], strict=True), macro_first,
                               strict=True):
            for frame in pair if first else pair[::-1]:
                published += [capture for _, capture in arbiter.on_frame(*frame)]
        outcomes.add(tuple(published))
    # macro@100: the micro camera did not see the robot then; macro@133 and macro@167 are
    # dropped (the micro camera saw it, still or not); micro@167 is the finest.
    assert outcomes == {('macro@100', 'micro@167')}


def test_a_coarse_capture_waits_for_the_finer_camera_s_frame_of_its_time():
    arbiter: CameraArbiter[str] = CameraArbiter(['micro', 'macro'])
    assert arbiter.on_frame('macro', 200, True, 'macro@200') == []
    assert arbiter.on_frame('micro', 167, False, None) == []       # older than the capture
    assert arbiter.on_frame('micro', 233, False, None) == [(200, 'macro@200')]
