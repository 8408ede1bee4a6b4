"""A stand-in for a machine-vision camera driver left on its defaults, written from those
drivers' conventions (the GigE / USB3 vendor drivers' ROS 2 wrappers), not from omni-micro's
nodes: a 1600 x 1200 sensor of 12 bits publishing ``mono16`` frames (3.8 MB each) and their
CameraInfo at 30 Hz, best effort (SensorDataQoS), stamped with the system clock when taken, in
``camera_optical_frame``. What its Fast DDS does is whatever the environment it is started in
says (no profile: Fast DDS's defaults, 0.5 MB shared-memory segments).

    python mono16_driver.py NAMESPACE SECONDS
"""

import sys
import time

import numpy as np
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image

WIDTH, HEIGHT, RATE_HZ = 1600, 1200, 30.0


class Mono16Driver(Node):
    def __init__(self, seconds: float) -> None:
        super().__init__('mono16_driver')
        self.images = self.create_publisher(Image, 'image_raw', qos_profile_sensor_data)
        self.infos = self.create_publisher(CameraInfo, 'camera_info', qos_profile_sensor_data)
        rng = np.random.default_rng(0)
        # 12-bit counts in 16-bit words, little-endian, as such drivers send them.
        self.pixels = (rng.integers(200, 400, (HEIGHT, WIDTH), dtype=np.uint16)).tobytes()
        self.sent = 0
        self.until = time.monotonic() + seconds
        self.create_timer(1.0 / RATE_HZ, self.on_frame)

    def on_frame(self) -> None:
        if time.monotonic() > self.until:
            raise SystemExit(0)
        stamp = self.get_clock().now().to_msg()
        image = Image(height=HEIGHT, width=WIDTH, encoding='mono16', is_bigendian=0,
                      step=2 * WIDTH, data=self.pixels)
        image.header.stamp, image.header.frame_id = stamp, 'camera_optical_frame'
        info = CameraInfo(height=HEIGHT, width=WIDTH, distortion_model='plumb_bob')
        info.header = image.header
        self.images.publish(image)
        self.infos.publish(info)
        self.sent += 1


def main() -> None:
    namespace, seconds = sys.argv[1], float(sys.argv[2])
    rclpy.init(args=['--ros-args', '-r', f'__ns:={namespace}'])
    node = Mono16Driver(seconds)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException, SystemExit):
        pass
    finally:
        print(f'sent {node.sent}', flush=True)
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
