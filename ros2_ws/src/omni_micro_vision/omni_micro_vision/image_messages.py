"""sensor_msgs/Image and pixels: what a frame from rclpy, from a bag or from a raw subscription
holds, checked; and a camera's frames and CameraInfo written as CDR directly.

A 1280 x 1024 frame is 1.3 MB: built as an rclpy message it was copied three times on its way
out (to bytes, to the C message, serialized) and twice on its way in. :class:`ImageWriter` joins
a serialized header to the pixels (one copy) and :func:`read_image` reads a raw message's pixels
where they lie (none); the bytes are those a publisher of the same message sends (tested).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from omni_micro_common.cdr import LITTLE_ENDIAN_CDR, MessageTemplate, read_string
from omni_micro_vision.encodings import encoding_of, grey
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import Lens

_STAMP = {'header.stamp.sec': 'int32', 'header.stamp.nanosec': 'uint32'}


class ImageLike(Protocol):
    """What a sensor_msgs/Image carries, whoever decoded it (rclpy, rosbags from a bag, or
    :func:`read_image` from a raw subscription)."""

    header: Any
    encoding: str
    width: int
    height: int
    step: int
    is_bigendian: int
    data: Any


def image_array(msg: ImageLike, expected: tuple[int, int] | None) -> np.ndarray:
    """The pixels of ``msg`` (a sensor_msgs/Image, from rclpy or read from a bag) in any
    encoding a driver commonly sends (:mod:`omni_micro_vision.encodings`) as one grey channel,
    rows x columns; a native little-endian mono frame without row padding is not copied.
    ``expected``: its (width, height), if known (the camera's geometry, or its CameraInfo).

    Raises
    ------
    CameraConfigError
        Naming what is wrong: the encoding, the size against ``expected``, the data length.
    """
    encoding = encoding_of(msg.encoding)
    if expected is not None and (msg.width, msg.height) != expected:
        raise CameraConfigError(f'image is {msg.width} x {msg.height}, expected '
                                f'{expected[0]} x {expected[1]}')
    if encoding.channels == 2 and msg.width % 2:
        raise CameraConfigError(f'a {msg.encoding} image of odd width {msg.width} (two pixels '
                                'share their colour)')
    if encoding.to_grey and encoding.to_grey.startswith('COLOR_Bayer') and (
            msg.width < 2 or msg.height < 2):
        raise CameraConfigError(f'a {msg.encoding} image of {msg.width} x {msg.height}: a '
                                'Bayer frame is at least 2 x 2')
    dtype = np.dtype(encoding.dtype).newbyteorder('>' if msg.is_bigendian else '<')
    row_bytes = msg.width * encoding.channels * dtype.itemsize
    if msg.step < row_bytes or len(msg.data) != msg.step * msg.height:
        raise CameraConfigError(f'{len(msg.data)} bytes of data for {msg.height} rows of step '
                                f'{msg.step} ({msg.width} pixels of {encoding.channels} x '
                                f'{dtype.itemsize} bytes)')
    rows = np.frombuffer(msg.data, dtype=np.uint8).reshape(msg.height, msg.step)
    samples = rows[:, :row_bytes]
    if msg.step != row_bytes:
        samples = samples.copy()    # padded rows: the view needs contiguous rows
    # A native little-endian frame is used as it is, with no copy.
    pixels = samples.view(dtype).astype(encoding.dtype, copy=False)
    if encoding.channels > 1:
        pixels = pixels.reshape(msg.height, msg.width, encoding.channels)
    return grey(pixels, encoding)


class ImageWriter:
    """One camera's frames as serialized sensor_msgs/Image, and their CameraInfo: the size,
    the frame and, with ``lens``, K, D (plumb_bob), R (identity) and P as image_pipeline reads
    them (without, all zero: an uncalibrated driver's)."""

    def __init__(self, frame_id: str, height: int, width: int, encoding: str,
                 lens: Lens | None = None) -> None:
        self.shape = (height, width)
        self.dtype = np.dtype(encoding_of(encoding).dtype).newbyteorder('<')
        itemsize = self.dtype.itemsize
        image = Image(height=height, width=width, encoding=encoding, is_bigendian=0,
                      step=width * itemsize)
        image.header.frame_id = frame_id
        # With no pixels the bytes end with the data's length (a uint32 of 0): the pixels
        # follow it directly (bytes need no alignment).
        self._head = MessageTemplate(image, _STAMP)
        info = CameraInfo(height=height, width=width)
        info.header.frame_id = frame_id
        if lens is not None and lens.calibrated:
            fx, _, cx, _, fy, cy = lens.camera_matrix[:6]
            info.distortion_model = 'plumb_bob'
            info.k = list(lens.camera_matrix)
            info.d = list(lens.distortion)
            info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
            info.p = [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        self._info = MessageTemplate(info, _STAMP)

    def image(self, sec: int, nanosec: int, pixels: np.ndarray) -> bytes:
        """The frame ``pixels`` (rows x columns of the encoding's type) stamped (sec, nanosec)."""
        if pixels.shape != self.shape or pixels.dtype != self.dtype:
            raise ValueError(f'pixels of shape {pixels.shape} and type {pixels.dtype}, '
                             f'expected {self.shape} of {self.dtype}')
        head = self._head.encode((sec, nanosec))
        return b''.join((head[:-4], struct.pack('<I', pixels.nbytes),
                         np.ascontiguousarray(pixels).data))

    def info(self, sec: int, nanosec: int) -> bytes:
        return self._info.encode((sec, nanosec))


@dataclass
class RawImage:
    """A sensor_msgs/Image read from its CDR bytes, its pixels left where they lie."""

    header: Header
    height: int
    width: int
    encoding: str
    is_bigendian: int
    step: int
    data: memoryview


def read_image(data: bytes) -> RawImage | Image:
    """The Image of a raw subscription: read in place if little-endian CDR (any publisher's;
    the pixels a view of ``data``), else deserialized by rclpy.

    Raises
    ------
    CameraConfigError
        If the bytes are not an Image (cut short, lengths that do not add up).
    """
    if data[:2] != LITTLE_ENDIAN_CDR[0]:   # plain CDR, little-endian
        return deserialize_message(data, Image)
    view = memoryview(data)
    try:
        sec, nanosec = struct.unpack_from('<iI', view, 4)
        frame_id, offset = read_string(view, 8)
        offset += -offset % 4
        height, width = struct.unpack_from('<II', view, 4 + offset)
        encoding, offset = read_string(view, offset + 8)
        is_bigendian = view[4 + offset]
        offset += 1
        offset += -offset % 4
        step, length = struct.unpack_from('<II', view, 4 + offset)
    except (struct.error, IndexError, UnicodeDecodeError) as error:
        raise CameraConfigError(f'an image message that does not parse: {error}') from None
    start = 4 + offset + 8
    # rclpy's serializer pads the end to four bytes: more may follow, not less.
    if start + length > len(view):
        raise CameraConfigError(f'an image message of {len(view)} bytes whose data says '
                                f'{length} bytes from byte {start}')
    return RawImage(Header(stamp=Time(sec=sec, nanosec=nanosec), frame_id=frame_id), height,
                    width, encoding, is_bigendian, step, view[start:start + length])
