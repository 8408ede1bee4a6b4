"""sensor_msgs/Image to pixels: what a frame from rclpy or from a bag holds, checked."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from omni_micro_vision.errors import CameraConfigError


class ImageLike(Protocol):
    """What a sensor_msgs/Image carries, whoever decoded it (rclpy, or rosbags from a bag)."""

    encoding: str
    width: int
    height: int
    step: int
    is_bigendian: int
    data: Any


DTYPES = {'mono8': np.uint8, 'mono16': np.uint16}


def image_array(msg: ImageLike, expected: tuple[int, int] | None) -> np.ndarray:
    """The pixels of ``msg`` (a sensor_msgs/Image, from rclpy or read from a bag) as a rows x
    columns array; a native little-endian frame without row padding is not copied.

    Raises
    ------
    CameraConfigError
        Naming what is wrong: the encoding, the size against the CameraInfo, the data length.
    """
    if msg.encoding not in DTYPES:
        raise CameraConfigError(f'encoding {msg.encoding!r} is not mono8 or mono16')
    if expected is not None and (msg.width, msg.height) != expected:
        raise CameraConfigError(f'image is {msg.width} x {msg.height}, its CameraInfo says '
                                f'{expected[0]} x {expected[1]}')
    dtype = np.dtype(DTYPES[msg.encoding]).newbyteorder('>' if msg.is_bigendian else '<')
    row_bytes = msg.width * dtype.itemsize
    if msg.step < row_bytes or len(msg.data) != msg.step * msg.height:
        raise CameraConfigError(f'{len(msg.data)} bytes of data for {msg.height} rows of step '
                                f'{msg.step} ({msg.width} pixels of {dtype.itemsize} bytes)')
    rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)
    pixels = rows[:, :row_bytes]
    if msg.step != row_bytes:
        pixels = pixels.copy()    # padded rows: the view needs contiguous rows
    # A native little-endian mono8/mono16 frame is used as it is, with no copy.
    return pixels.view(dtype).astype(DTYPES[msg.encoding], copy=False)
