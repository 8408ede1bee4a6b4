"""Image encodings by their ROS names (``sensor_msgs/image_encodings.hpp``) and their grey level.

The tracker looks at brightness only, so a frame of any encoding a camera driver sends is made
one grey channel with OpenCV's ``cvtColor``, as cv_bridge and image_proc's debayer do. OpenCV
names a Bayer pattern after the second row's first two pixels, so ROS's ``bayer_rggb8`` is
OpenCV's ``BayerBG`` (cv_bridge's table; tests/vision/test_encodings.py checks each pattern
against a mosaic made from its definition).

No rclpy: a plain module, read by ``image_messages`` and by ``omni-micro track``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from omni_micro_vision.errors import CameraConfigError


@dataclass(frozen=True)
class Encoding:
    """How one encoding lays out a pixel, and the OpenCV code that makes it grey."""

    name: str
    dtype: type[np.unsignedinteger]
    channels: int          # samples per pixel in the message's data
    to_grey: str | None    # the name of a cv2.COLOR_* code; None: already one grey channel


_BAYER = {'rggb': 'BayerBG', 'bggr': 'BayerRG', 'gbrg': 'BayerGR', 'grbg': 'BayerGB'}

ENCODINGS: dict[str, Encoding] = {
    encoding.name: encoding for encoding in (
        Encoding('mono8', np.uint8, 1, None),
        Encoding('mono16', np.uint16, 1, None),
        Encoding('rgb8', np.uint8, 3, 'COLOR_RGB2GRAY'),
        Encoding('bgr8', np.uint8, 3, 'COLOR_BGR2GRAY'),
        Encoding('rgba8', np.uint8, 4, 'COLOR_RGBA2GRAY'),
        Encoding('bgra8', np.uint8, 4, 'COLOR_BGRA2GRAY'),
        # UYVY and YUYV: two bytes a pixel, the grey level is Y.
        Encoding('yuv422', np.uint8, 2, 'COLOR_YUV2GRAY_UYVY'),
        Encoding('yuv422_yuy2', np.uint8, 2, 'COLOR_YUV2GRAY_YUY2'),
        *(Encoding(f'bayer_{pattern}{bits}', np.uint8 if bits == 8 else np.uint16, 1,
                   f'COLOR_{code}2GRAY')
          for pattern, code in _BAYER.items() for bits in (8, 16)),
    )}


def encoding_of(name: str) -> Encoding:
    """The encoding named ``name``.

    Raises
    ------
    CameraConfigError
        Naming the encoding and the ones the tracker reads.
    """
    try:
        return ENCODINGS[name]
    except KeyError:
        raise CameraConfigError(f'encoding {name!r} is not one the tracker reads: '
                                f'{", ".join(ENCODINGS)}') from None


def grey(samples: np.ndarray, encoding: Encoding) -> np.ndarray:
    """One grey channel (rows x columns, uint8 or uint16) of ``samples`` (rows x columns, x
    channels when more than one) in ``encoding``; a grey frame is returned as it is."""
    if encoding.to_grey is None:
        return samples
    import cv2

    converted: np.ndarray = cv2.cvtColor(np.ascontiguousarray(samples),
                                         getattr(cv2, encoding.to_grey))
    return converted


# What a mono16 frame's counts can span: sensors of 10 to 16 bits send their counts as they
# are in 16-bit words.
BIT_DEPTHS = (8, 10, 12, 14, 16)


def checked_bit_depth(name: str, value: object) -> int:
    """A camera's ``bit_depth`` parameter: 0 (from the frames) or one of :data:`BIT_DEPTHS`."""
    if isinstance(value, bool) or value not in (0, *BIT_DEPTHS):
        raise CameraConfigError(f'{name} must be 0 (read it from the frames) or one of '
                                f'{list(BIT_DEPTHS)}, got {value!r}')
    return int(value)


def full_scale(image: np.ndarray, bit_depth: int) -> int:
    """The largest count ``image`` can hold: ``2**bit_depth - 1``, or, with ``bit_depth`` 0,
    that of the least of :data:`BIT_DEPTHS` that holds its brightest pixel (a 12-bit sensor's
    frame in mono16 is then read on 4095 counts, not 65535, and the tracker's thresholds hold).
    """
    if bit_depth:
        return (1 << bit_depth) - 1
    if image.dtype == np.uint8:
        return 255
    brightest = int(image.max()) if image.size else 0
    return next((1 << bits) - 1 for bits in BIT_DEPTHS if brightest < 1 << bits)
