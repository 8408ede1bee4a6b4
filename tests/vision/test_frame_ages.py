"""How old a driver's frames come, by their stamps against this machine's clock: said after the
first few frames and then every window, the largest age of the latest frames; nothing said of
frames on simulated time."""

import pytest

from omni_micro_vision.frame_ages import FrameAges

WALL_NS = 1_796_000_000 * 10**9     # a stamp on the wall clock (2026)


def test_the_oldest_of_the_latest_frames_is_said_after_five_then_every_window():
    ages = FrameAges(capture_after_stamp_s=0.004, window=10)
    said = []
    for index in range(25):
        stamp = WALL_NS + index * 66_666_667              # 15 Hz
        arrived = stamp + (80 if index == 3 else 30) * 10**6
        said.append(ages.add(stamp, arrived, arrived + 5 * 10**6))
    assert [index for index, due in enumerate(said) if due] == [4, 14, 24]
    # Frame 3 came 80 ms after its stamp; it is no longer among the latest ten at the end.
    assert ages.frame_age_s == pytest.approx(0.030)
    # A capture in motion is stamped 4 ms after its frame, published 5 ms after it came.
    assert ages.capture_age_s == pytest.approx(0.031)
    assert ages.frame_rate_hz == pytest.approx(15.0, rel=1e-6)
    values = dict(ages.values('/bench/camera/image_raw'))
    assert values == {'frame_age_s': '0.0300', 'capture_age_s': '0.0310',
                      'frame_rate_hz': '15.00', 'image_topic': '/bench/camera/image_raw'}


def test_frames_on_simulated_time_have_no_age_to_say():
    ages = FrameAges()
    assert not any(ages.add(index * 10**8, WALL_NS + index * 10**8, WALL_NS + index * 10**8)
                   for index in range(40))
