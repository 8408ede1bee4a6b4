"""Frames a driver sent that never reached the tracker, counted from the gaps in their stamps:
the driver's rate read from the stamps that arrive, every lost frame counted, a stretch said
once when it has lasted a second and again with its final figures when it ends, and the cause
named with what to do."""

import random

import pytest

from omni_micro_vision.frame_losses import FrameLosses, likely_cause

PERIOD_NS = 33_333_333          # a driver at 30 Hz
CAUSE = 'the cause'


def period_of(losses: FrameLosses) -> float:
    assert losses.period_ns is not None
    return losses.period_ns


def feed(losses: FrameLosses, arrived: list[int], jitter_ns: int = 300_000, seed: int = 1):
    rng = random.Random(seed)
    said = []
    for index in arrived:
        stretch = losses.add(10**9 + index * PERIOD_NS + rng.randint(-jitter_ns, jitter_ns),
                             lambda: CAUSE)
        if stretch is not None:
            said.append((index, stretch))
    return said


def test_frames_that_arrive_whole_are_never_said_lost():
    losses = FrameLosses('macro', '/camera/macro/image_raw')
    assert feed(losses, list(range(600))) == []
    assert (losses.lost_total, losses.sent_total) == (0, 599)
    assert 1e9 / period_of(losses) == pytest.approx(30.0, rel=1e-3)


def test_every_lost_frame_is_counted_even_when_most_are_lost():
    """Three frames in four lost for fifteen seconds (about 7 Hz of 30 arriving, as a 3.8 MB
    mono16 driver on Fast DDS's defaults gave): two in a row arrive only now and then, and the
    rate is still the driver's."""
    rng = random.Random(7)
    dropped = {index for index in range(60, 510) if rng.random() < 0.75}
    losses = FrameLosses('macro', '/camera/macro/image_raw')
    arrived = [index for index in range(900) if index not in dropped]
    said = feed(losses, arrived)
    assert losses.lost_total == len(dropped)
    first_dropped = min(dropped)
    (at, began), (_, ended) = said
    # Said once when it had lasted a second, then its final figures two quiet seconds on.
    assert (began.said, began.ended) == (False, False)
    assert (ended.said, ended.ended) == (True, True)
    assert began.since_ns == pytest.approx(10**9 + first_dropped * PERIOD_NS, abs=1e6)
    # Said at the first frame that came a second or more into the stretch.
    assert at - first_dropped >= 29
    assert arrived[arrived.index(at) - 1] - first_dropped <= 30
    assert ended.lost == len(dropped)
    assert ended.sent_hz == pytest.approx(30.0, rel=1e-3)
    assert ended.arrived_hz == pytest.approx(30.0 * (ended.sent - ended.lost) / ended.sent,
                                             rel=1e-3)
    assert began.message().startswith(
        f'macro: {began.lost} of {began.sent} frames from /camera/macro/image_raw lost since ')
    assert began.message().endswith('the driver sends 30.0 Hz by its stamps, '
                                    f'{began.arrived_hz:.1f} Hz arrive; {CAUSE}')


def test_each_stretch_is_said_on_its_own():
    dropped = {100, 101, 102, 103, 104, 105, 300, 330, 331, 360, 400}
    losses = FrameLosses('micro', '/camera/micro/image_raw')
    said = feed(losses, [index for index in range(700) if index not in dropped])
    began = [stretch for _, stretch in said if not stretch.ended]
    ended = [stretch for _, stretch in said if stretch.ended]
    # Frames 100-105, then 300-400 (never two quiet seconds between: one stretch), each said
    # when a second old and with its final figures once two seconds passed with no loss (at
    # frames 166 and 461).
    assert [(s.lost, s.sent, s.said) for s in ended] == [(6, 66, True), (5, 162, True)]
    assert [(s.lost, s.said) for s in began] == [(6, False), (3, False)]
    assert losses.lost_total == len(dropped)


def test_a_driver_that_restarts_its_clock_loses_nothing():
    losses = FrameLosses('macro', '/camera/macro/image_raw')
    feed(losses, list(range(100)))
    assert feed(losses, list(range(100)), seed=2) == []
    assert losses.lost_total == 0


def test_the_cause_names_what_to_do():
    profile = '/opt/omni/share/omni_micro_common/config/fastdds.xml'
    large = likely_cause(1600 * 1200 * 2, True, 0.004, 1 / 30, profile, 10)
    assert large == ('likely cause: 3.7 MB frames read best effort through Fast DDS\'s default '
                     '0.5 MB shared-memory segments; start the driver with the project\'s '
                     f'profile: export FASTRTPS_DEFAULT_PROFILES_FILE={profile}')
    slow = likely_cause(1600 * 1200, False, 0.050, 1 / 30, profile, 10)
    assert slow.startswith('likely cause: the tracker takes 50.0 ms a frame, longer than the '
                           'driver\'s 33.3 ms period, and its queue (depth 10) drops the rest')
    # A busy machine's tracker slower than a driver on the defaults: both said.
    both = likely_cause(1600 * 1200 * 2, True, 0.050, 1 / 30, profile, 10)
    assert both.startswith('likely causes: 3.7 MB frames read best effort')
    assert both.endswith('; and ' + slow.removeprefix('likely cause: '))
    small = likely_cause(320 * 240, True, 0.004, 1 / 30, profile, 10)
    assert small.startswith('likely cause: the transport')
    # A reliable reader's writer resends what the segment could not hold: not that cause.
    assert likely_cause(1600 * 1200 * 2, False, 0.004, 1 / 30, profile, 10) == small


def test_since_is_a_time_of_day_on_the_wall_clock_and_seconds_on_another():
    from omni_micro_vision.frame_losses import LossStretch

    wall_ns = 1_796_441_734_619_000_000     # 2026-12-04 03:35:34.619 UTC
    stretch = LossStretch('macro', '/cam/image_raw', wall_ns, 19, 32, 30.0, CAUSE)
    assert 'lost since 03:35:34.619 UTC: ' in stretch.message(wall_ns + 10**9)
    simulated = LossStretch('macro', '/cam/image_raw', 2_367_000_000, 19, 32, 30.0, CAUSE)
    assert "lost since 2.367 s of the driver's clock: " in simulated.message(wall_ns)


def test_every_third_frame_is_read_as_a_30_hz_driver_by_its_camera_info():
    """A large frame through too small a segment came every third period, as steadily as a
    10 Hz driver's would: the frames' gaps alone cannot tell; the CameraInfo, small, comes with
    every frame's stamp and tells."""
    alone = FrameLosses('macro', '/cam/image_raw')
    assert feed(alone, list(range(0, 600, 3))) == []
    assert 1e9 / period_of(alone) == pytest.approx(10.0, rel=1e-3)

    losses = FrameLosses('macro', '/cam/image_raw')
    said = []
    for index in range(600):
        stamp = 10**9 + index * PERIOD_NS
        losses.add_info(stamp)
        if index % 3 == 0:
            stretch = losses.add(stamp, lambda: CAUSE)
            said += [stretch] if stretch else []
    assert 1e9 / period_of(losses) == pytest.approx(30.0, rel=1e-6)
    # A frame that comes before its CameraInfo (another topic, another reader) is no loss.
    reversed_order = FrameLosses('macro', '/cam/image_raw')
    for index in range(100):
        stamp = 10**9 + index * PERIOD_NS
        assert reversed_order.add(stamp, lambda: CAUSE) is None
        reversed_order.add_info(stamp)
    assert reversed_order.lost_total == 0
    assert said[0].sent_hz == pytest.approx(30.0) and said[0].arrived_hz == pytest.approx(10.0)
    # Each CameraInfo whose frame never came is a frame lost: two between each two frames.
    assert losses.lost_total == 2 * (len(range(0, 600, 3)) - 1)
    # A driver that cannot keep its rate (its frames irregular, none lost) loses nothing, and
    # its rate is what it sent.
    irregular = FrameLosses('micro', '/cam/image_raw')
    rng = random.Random(3)
    stamp = 10**9
    for _ in range(300):
        stamp += round(PERIOD_NS * rng.uniform(1.0, 2.0))
        irregular.add_info(stamp)
        assert irregular.add(stamp, lambda: CAUSE) is None
    assert irregular.lost_total == 0
    assert 1e9 / period_of(irregular) == pytest.approx(299 / ((stamp - 10**9) * 1e-9) * 300
                                                       / 299, rel=0.02)


def test_a_camera_info_lost_on_the_way_leaves_the_rate_the_driver_sent():
    """Best effort, a CameraInfo is lost too now and then (1 of 54 in a suite run): its frame,
    which came, still says a frame was sent, and the rate is the driver's, not 2 % less."""
    losses = FrameLosses('micro', '/cam/image_raw')
    for index in range(60):
        stamp = 10**9 + index * PERIOD_NS
        if index % 20 != 7:
            losses.add_info(stamp)
        assert losses.add(stamp, lambda: CAUSE) is None
    assert 1e9 / period_of(losses) == pytest.approx(30.0, rel=1e-6)
    assert losses.lost_total == 0


def test_a_late_frame_and_the_one_soon_after_are_not_lost_frames():
    """A driver that stamps a frame when it gets to it (usb_cam stamps on grabbing) sends one
    late now and then and the next soon after: no frame is lost, and the rate is still 30 Hz."""
    losses = FrameLosses('macro', '/cam/image_raw')
    said = []
    for index in range(600):
        late = 0.4 * PERIOD_NS if index % 7 == 3 else 0.0
        stretch = losses.add(round(10**9 + index * PERIOD_NS + late), lambda: CAUSE)
        said += [stretch] if stretch else []
    assert said == [] and losses.lost_total == 0
    assert 1e9 / period_of(losses) == pytest.approx(30.0, rel=1e-3)


def test_camera_info_without_frames_is_kept_within_bounds():
    """A driver whose frames never come at all (the image topic mistyped, say): the CameraInfo
    waiting for them is bounded, not kept for ever."""
    from omni_micro_vision.frame_losses import PENDING_LIMIT

    losses = FrameLosses('macro', '/cam/image_raw')
    for index in range(10 * PENDING_LIMIT):
        losses.add_info(10**9 + index * PERIOD_NS)
    assert len(losses._pending) == PENDING_LIMIT
