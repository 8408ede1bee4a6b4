"""Frames as camera drivers send them (omni_micro_vision.encodings): every encoding the tracker
reads gives the pose the mono frame gives, within that frame's noise.

Each colour frame is made here from a rendered mono frame by the encoding's own definition
(sensor_msgs/image_encodings.hpp; a Bayer pattern names the colours of its first 2 x 2 pixels;
UYVY is U Y0 V Y1, YUYV is Y0 U Y1 V), not by the code under test, and with a colour cast a
real scene has, so that a wrong channel order or Bayer code shows.
"""

import math

import numpy as np
import pytest
from sensor_msgs.msg import Image

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import DEFAULT_RIG
from omni_micro_vision.encodings import ENCODINGS, checked_bit_depth
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import PlaneMap
from omni_micro_vision.image_messages import image_array
from omni_micro_vision.rendering import Sensor, render
from omni_micro_vision.tracking import FrameTracker

CAMERA = DEFAULT_RIG.micro
TRUTH = RobotState(0.1001, 0.0002, 2.0)
# A warm light: red a little stronger than green, blue weaker (fractions of the grey level).
CAST = {'r': 1.0, 'g': 0.9, 'b': 0.7}
BAYER_PATTERNS = ('rggb', 'bggr', 'gbrg', 'grbg')
# Three times the tracker's own spread on mono frames of the micro camera (docs/images.md,
# "Accuracy": 7 nm, 0.023 mrad): a pose within it is the mono frame's within its noise.
MONO_SPREAD_M = 21e-9
MONO_SPREAD_RAD = 0.07e-3


def message(samples: np.ndarray, encoding: str) -> Image:
    rows, columns = samples.shape[:2]
    data = np.ascontiguousarray(samples)
    return Image(height=rows, width=columns, encoding=encoding, is_bigendian=0,
                 step=data.strides[0], data=data.tobytes())


def colour(grey: np.ndarray, order: str) -> np.ndarray:
    """Channels in ``order`` (e.g. 'rgb', 'bgra') of a grey frame under the colour cast."""
    top = np.iinfo(grey.dtype).max
    planes = [np.full_like(grey, top) if name == 'a' else
              np.round(grey * CAST[name]).astype(grey.dtype) for name in order]
    return np.dstack(planes)


def mosaic(grey: np.ndarray, pattern: str) -> np.ndarray:
    """A Bayer frame: each pixel keeps the one colour its place in ``pattern`` names."""
    channels = {name: np.round(grey * CAST[name]).astype(grey.dtype) for name in 'rgb'}
    result = np.empty_like(grey)
    for index, name in enumerate(pattern):
        row, column = divmod(index, 2)
        result[row::2, column::2] = channels[name][row::2, column::2]
    return result


def yuv422(grey: np.ndarray, order: str) -> np.ndarray:
    """Two bytes a pixel: luma Y, and neutral chroma (128) shared by pairs of pixels."""
    pairs = grey.reshape(grey.shape[0], -1, 2)
    chroma = np.full(pairs.shape[:2], 128, np.uint8)
    parts = {'u': chroma, 'v': chroma, 'y0': pairs[..., 0], 'y1': pairs[..., 1]}
    return np.stack([parts[name] for name in order.split()], axis=-1).reshape(
        grey.shape[0], grey.shape[1], 2)


def frames(bit_depth: int) -> dict[str, Image]:
    grey = render(CAMERA, Sensor(bit_depth=bit_depth), TRUTH, np.random.default_rng(1))
    if bit_depth == 8:
        made = {'mono8': message(grey, 'mono8'),
                **{name: message(colour(grey, name[:-1]), name)
                   for name in ('rgb8', 'bgr8', 'rgba8', 'bgra8')},
                'yuv422': message(yuv422(grey, 'u y0 v y1'), 'yuv422'),
                'yuv422_yuy2': message(yuv422(grey, 'y0 u y1 v'), 'yuv422_yuy2')}
    else:
        made = {'mono16': message(grey, 'mono16')}
    made.update({f'bayer_{pattern}{bit_depth}': message(mosaic(grey, pattern),
                                                        f'bayer_{pattern}{bit_depth}')
                 for pattern in BAYER_PATTERNS})
    return made


def pose(msg: Image) -> tuple[float, float, float]:
    plane = PlaneMap.nominal(CAMERA)
    found = FrameTracker(plane)(image_array(msg, plane.resolution_px))
    assert found.pose is not None, f'{msg.encoding}: {found.reason}'
    return found.pose


@pytest.mark.parametrize('bit_depth', [8, 16])
def test_every_encoding_gives_the_mono_frames_pose_within_its_noise(bit_depth):
    made = frames(bit_depth)
    reference = pose(made[f'mono{bit_depth}'])
    for encoding, msg in made.items():
        x, y, phi = pose(msg)
        assert math.hypot(x - reference[0], y - reference[1]) < MONO_SPREAD_M, encoding
        assert abs(math.remainder(phi - reference[2], math.tau)) < MONO_SPREAD_RAD, encoding
    assert set(made) | set(frames(24 - bit_depth)) == set(ENCODINGS)


@pytest.mark.parametrize('pattern', BAYER_PATTERNS)
def test_each_bayer_pattern_is_read_with_its_own_colours(pattern):
    """A red-and-blue scene: its grey level is mostly red's weight (0.299) against blue's
    (0.114), so a pattern read with red and blue swapped is far off."""
    rows, columns = 64, 80
    red = np.full((rows, columns), 200, np.uint8)
    blue = np.zeros((rows, columns), np.uint8)
    blue[:, columns // 2:] = 150
    rgb = np.dstack([red, np.zeros_like(red), blue])
    raw = np.empty((rows, columns), np.uint8)
    for index, name in enumerate(pattern):
        row, column = divmod(index, 2)
        raw[row::2, column::2] = rgb[row::2, column::2, 'rgb'.index(name)]
    grey = image_array(message(raw, f'bayer_{pattern}8'), None).astype(float)
    expected = 0.299 * red + 0.114 * blue.astype(float)
    inner = (slice(4, -4), np.r_[4:columns // 2 - 4, columns // 2 + 4:columns - 4])
    assert np.abs(grey[inner] - expected[inner]).max() <= 2.0


def test_a_12_bit_sensor_in_mono16_is_read_on_its_own_scale():
    """Counts of a 12-bit sensor in 16-bit words: found with the depth read from the frames or
    given; read as 16-bit counts, nothing is bright enough (what the node did before)."""
    grey = render(CAMERA, Sensor(bit_depth=16), TRUTH, np.random.default_rng(1)) >> 4
    msg = message(grey, 'mono16')
    pixels = image_array(msg, None)
    assert pixels.max() < 4096
    plane = PlaneMap.nominal(CAMERA)
    detected, given = FrameTracker(plane)(pixels), FrameTracker(plane, 12)(pixels)
    assert detected.pose is not None and detected.pose == given.pose
    assert math.hypot(detected.pose[0] - TRUTH.x_m, detected.pose[1] - TRUTH.y_m) < 0.1e-6
    wrong = FrameTracker(plane, 16)(pixels)
    assert wrong.reason == 'no fiducial: nothing brighter than the platform'
    with pytest.raises(CameraConfigError, match=r'micro.bit_depth must be 0 \(read it from the '
                                                r'frames\) or one of \[8, 10, 12, 14, 16\], '
                                                r'got 11'):
        checked_bit_depth('micro.bit_depth', 11)


@pytest.mark.parametrize(('encoding', 'columns', 'match'), [
    ('32FC1', 8, "encoding '32FC1' is not one the tracker reads: mono8, mono16, rgb8, bgr8"),
    ('yuv422', 7, 'a yuv422 image of odd width 7'),
    ('bayer_rggb8', 1, 'a Bayer frame is at least 2 x 2'),
])
def test_a_frame_the_tracker_cannot_read_is_refused_naming_why(encoding, columns, match):
    samples = np.zeros((4, columns * (2 if encoding == 'yuv422' else 1)), np.uint8)
    msg = Image(height=4, width=columns, encoding=encoding, step=samples.shape[1],
                data=samples.tobytes())
    with pytest.raises(CameraConfigError, match=match):
        image_array(msg, None)
