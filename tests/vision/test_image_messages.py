"""A camera's frames on the wire (omni_micro_vision.image_messages): the bytes camera_node
publishes are rosbags' serialization of the same Image and CameraInfo, byte for byte, and a raw
subscription reads any publisher's Image back, its pixels where they lie."""

import numpy as np
import pytest
from rclpy.serialization import deserialize_message, serialize_message
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_common.cdr import canonical_bytes
from omni_micro_vision.errors import CameraConfigError
from omni_micro_vision.geometry import Lens
from omni_micro_vision.image_messages import ImageWriter, image_array, read_image

# Frame ids of four lengths: the fields after them fall on every alignment.
FRAMES = ['camera_macro', 'cam_a', 'cam_ab', 'cam_abc']


def pixels_of(encoding: str, rows: int = 6, columns: int = 10) -> np.ndarray:
    dtype = np.uint8 if encoding == 'mono8' else np.uint16
    values = np.random.default_rng(3).integers(0, np.iinfo(dtype).max, (rows, columns))
    return values.astype(dtype)


def rclpy_image(frame_id: str, pixels: np.ndarray, encoding: str) -> Image:
    image = Image(height=pixels.shape[0], width=pixels.shape[1], encoding=encoding,
                  is_bigendian=0, step=pixels.shape[1] * pixels.itemsize)
    image.header.frame_id = frame_id
    image.header.stamp.sec, image.header.stamp.nanosec = 12, 345_000_000
    image.data = pixels.tobytes()
    return image


def written(frame_id: str, encoding: str) -> tuple[np.ndarray, ImageWriter, bytes]:
    """Pixels, the writer of their camera, and the frame it writes of them at 12.345 s."""
    pixels = pixels_of(encoding)
    writer = ImageWriter(frame_id, pixels.shape[0], pixels.shape[1], encoding)
    return pixels, writer, writer.image(12, 345_000_000, pixels)


@pytest.mark.parametrize('encoding', ['mono8', 'mono16'])
@pytest.mark.parametrize('frame_id', FRAMES)
def test_frames_are_the_bytes_of_the_same_message(frame_id, encoding):
    pixels, writer, data = written(frame_id, encoding)
    assert data == canonical_bytes(rclpy_image(frame_id, pixels, encoding))
    info = CameraInfo(height=pixels.shape[0], width=pixels.shape[1])
    info.header.frame_id = frame_id
    info.header.stamp.sec, info.header.stamp.nanosec = 12, 345_000_000
    assert writer.info(12, 345_000_000) == canonical_bytes(info)
    assert deserialize_message(writer.info(12, 345_000_000), CameraInfo) == info


@pytest.mark.parametrize('frame_id', FRAMES)
def test_a_calibrated_camera_info_is_the_bytes_of_the_same_message(frame_id):
    lens = Lens((2560.0, 0.0, 639.5, 0.0, 2048.0, 511.5, 0.0, 0.0, 1.0),
                (-0.2, 0.05, 0.0, 0.0, 0.0))
    writer = ImageWriter(frame_id, 1024, 1280, 'mono8', lens)
    info = CameraInfo(height=1024, width=1280, distortion_model='plumb_bob',
                      d=[-0.2, 0.05, 0.0, 0.0, 0.0], k=list(lens.camera_matrix),
                      r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                      p=[2560.0, 0.0, 639.5, 0.0, 0.0, 2048.0, 511.5, 0.0, 0.0, 0.0, 1.0, 0.0])
    info.header.frame_id = frame_id
    info.header.stamp.sec, info.header.stamp.nanosec = 12, 345_000_000
    assert writer.info(12, 345_000_000) == canonical_bytes(info)


@pytest.mark.parametrize('encoding', ['mono8', 'mono16'])
@pytest.mark.parametrize('frame_id', FRAMES)
def test_a_raw_image_reads_back_from_ours_and_from_rclpys_bytes(frame_id, encoding):
    pixels, _, ours = written(frame_id, encoding)
    # rclpy's serializer may pad the end to four bytes: another publisher's layout.
    theirs = serialize_message(rclpy_image(frame_id, pixels, encoding))
    for data in (ours, theirs):
        image = read_image(data)
        assert image.header.frame_id == frame_id
        assert (image.header.stamp.sec, image.header.stamp.nanosec) == (12, 345_000_000)
        assert (image.height, image.width, image.encoding) == (*pixels.shape, encoding)
        np.testing.assert_array_equal(image_array(image, None), pixels)


def test_a_raw_image_is_not_copied():
    pixels = pixels_of('mono8', 1024, 1280)
    data = ImageWriter('camera_macro', 1024, 1280, 'mono8').image(0, 0, pixels)
    read = image_array(read_image(data), (1280, 1024))
    assert np.shares_memory(read, np.frombuffer(data, np.uint8))


def test_a_big_endian_message_is_deserialized_instead():
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_JAZZY)
    pixels = pixels_of('mono16')
    bag_image = store.deserialize_cdr(canonical_bytes(rclpy_image('cam', pixels, 'mono16')),
                                      'sensor_msgs/msg/Image')
    data = bytes(store.serialize_cdr(bag_image, 'sensor_msgs/msg/Image', little_endian=False))
    assert data[:2] == b'\x00\x00'   # CDR_BE
    image = read_image(data)
    assert isinstance(image, Image) and image.header.frame_id == 'cam'
    np.testing.assert_array_equal(image_array(image, None), pixels)


@pytest.mark.parametrize('cut', [3, 10, 40, -1])
def test_a_message_cut_short_is_refused_by_name(cut):
    data = ImageWriter('camera_macro', 6, 10, 'mono8').image(1, 2, pixels_of('mono8'))
    with pytest.raises(CameraConfigError, match='image message'):
        read_image(data[:cut])


def test_pixels_of_another_size_or_type_are_refused():
    writer = ImageWriter('camera_macro', 6, 10, 'mono8')
    with pytest.raises(ValueError, match='shape'):
        writer.image(0, 0, pixels_of('mono16'))
    with pytest.raises(ValueError, match='shape'):
        writer.image(0, 0, pixels_of('mono8', 5, 10))
