"""A stand-in for a real camera driver, written from the conventions of ROS 2 camera drivers
(usb_cam, v4l2_camera, the GigE and USB3 vendor drivers), not from omni-micro's nodes.

What such a driver does: it publishes ``image_raw`` and ``camera_info`` in its namespace, best
effort (SensorDataQoS, as the machine-vision drivers do), each frame stamped with the system
clock when it was taken, the image and its CameraInfo with one stamp, in the camera's
``<name>_optical_frame``, in the sensor's own encoding (a colour camera in raw mode: a Bayer
pattern; else rgb8), at its own resolution and rate; its CameraInfo carries K, D (plumb_bob),
R and P from its intrinsic calibration. It knows nothing of the robot or the controller.

What it sees is drawn by omni-micro's renderer and optics (the world, not the driver): the
robot where /bench_truth/odom says it is (the stand-in robot's true pose), or a chessboard
lying on the platform. The grey frame becomes the sensor's encoding here, from the
encoding's definition (a Bayer pattern keeps one colour per pixel), under a warm light.

    python camera_driver.py NAMESPACE ENCODING SCENE [CLOCK_OFFSET_S [FIRST_FRAME_AFTER_S]]
    (SCENE: robot or chessboard; CLOCK_OFFSET_S: how far this machine's clock is off;
    FIRST_FRAME_AFTER_S: its device opens that long after the node, which streams nothing
    until then, as a driver waiting for its camera does)
"""

import math
import sys
import time

import numpy as np
import rclpy
import rclpy.time
from nav_msgs.msg import Odometry
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image

from omni_micro_sim.state import RobotState
from omni_micro_vision.camera import CameraModel
from omni_micro_vision.optics import CameraOptics
from omni_micro_vision.rendering import Sensor, expose, render
from omni_micro_vision.targets import Chessboard, render_target

# The camera: 1280 x 1024 pixels of 1.72 um on the platform, over the micro work platform,
# turned 0.5 rad, mirrored by a fold mirror, a lens bending its corners by 1 %.
CAMERA = CameraModel('bench', (0.1, 0.0), (1280 * 1.72e-6, 1024 * 1.72e-6), (1280, 1024))
OPTICS = CameraOptics(CAMERA, yaw_rad=0.5, mirrored=True, working_distance_m=0.006,
                      distortion=(-0.3, 0.1))
FRAME_RATE_HZ = 15.0
# The line it prints for each frame it publishes, with the frame's stamp in nanoseconds.
SENT_FRAME = 'sent frame stamped'
TARGET = Chessboard((9, 6), 0.12e-3, (0.1001, 0.0), math.radians(10.0))
LIGHT = {'r': 1.0, 'g': 0.9, 'b': 0.7}


def to_encoding(grey: np.ndarray, encoding: str) -> np.ndarray:
    channels = {name: np.round(grey * gain).astype(np.uint8) for name, gain in LIGHT.items()}
    if encoding == 'rgb8':
        return np.dstack([channels['r'], channels['g'], channels['b']])
    pattern = encoding[len('bayer_'):len('bayer_') + 4]
    mosaic = np.empty_like(grey)
    for index, colour in enumerate(pattern):
        row, column = divmod(index, 2)
        mosaic[row::2, column::2] = channels[colour][row::2, column::2]
    return mosaic


class StandInCamera(Node):
    def __init__(self, encoding: str, scene: str, clock_offset_s: float = 0.0,
                 first_frame_after_s: float = 0.0) -> None:
        super().__init__('camera')
        self.device_open_at = time.monotonic() + first_frame_after_s
        self.clock_offset_ns = round(clock_offset_s * 1e9)
        self.encoding = encoding
        self.scene = scene
        self.images = self.create_publisher(Image, 'image_raw', qos_profile_sensor_data)
        self.infos = self.create_publisher(CameraInfo, 'camera_info', qos_profile_sensor_data)
        self.truth: RobotState | None = None
        self.truth_stamp_ns = 0
        self.drawn_ns = -1     # the true pose's time the latest frame shows
        self.create_subscription(Odometry, '/bench_truth/odom', self.on_truth, 10)
        self.sensor = Sensor()
        self.target = (render_target(CAMERA, TARGET, OPTICS.yaw_rad)
                       if scene == 'chessboard' else None)
        OPTICS.prepare()
        self.frame = 0
        self.create_timer(1.0 / FRAME_RATE_HZ, self.on_frame)

    def on_truth(self, msg: Odometry) -> None:
        pose, twist = msg.pose.pose, msg.twist.twist
        phi = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
        self.truth = RobotState(pose.position.x, pose.position.y, phi, twist.linear.x,
                                twist.linear.y, twist.angular.z)
        self.truth_stamp_ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec

    def on_frame(self) -> None:
        if time.monotonic() < self.device_open_at:
            return
        # When it was taken, by the system clock (on a machine whose clock may be off). The robot
        # is drawn where it really was at a moment the stand-in knows: its latest true pose, and
        # the frame stamped with that pose's time. (Drawn at the latest pose but stamped "now",
        # a frame of a machine too busy to take every pose in time showed the robot where it had
        # been: three such frames agree, and the tracker called a moving robot still there.)
        rng = np.random.default_rng([7, self.frame])
        if self.target is not None:
            taken_ns = self.get_clock().now().nanoseconds
            ideal = expose(self.target, self.sensor, rng)
        elif self.truth is not None and self.truth_stamp_ns != self.drawn_ns:
            taken_ns = self.drawn_ns = self.truth_stamp_ns
            ideal = render(CAMERA, self.sensor, self.truth, rng, OPTICS.yaw_rad)
        else:
            return    # no pose yet, or none since the last frame: no frame to take
        self.frame += 1
        stamp = rclpy.time.Time(nanoseconds=taken_ns + self.clock_offset_ns).to_msg()
        samples = to_encoding(OPTICS.view(ideal), self.encoding)
        image = Image(height=samples.shape[0], width=samples.shape[1], encoding=self.encoding,
                      is_bigendian=0, step=samples.strides[0])
        image.header.stamp = stamp
        image.header.frame_id = 'bench_optical_frame'
        image.data = samples.tobytes()
        lens = OPTICS.lens
        fx, _, cx, _, fy, cy = lens.camera_matrix[:6]
        info = CameraInfo(height=image.height, width=image.width, distortion_model='plumb_bob',
                          d=list(lens.distortion), k=list(lens.camera_matrix),
                          r=[1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
                          p=[fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0])
        info.header = image.header
        self.infos.publish(info)
        self.images.publish(image)
        # What it sent, for the test beside it: its best-effort readers may each lose frames.
        print(f'{SENT_FRAME} {taken_ns + self.clock_offset_ns}', flush=True)


def main() -> None:
    namespace, encoding, scene = sys.argv[1:4]
    offset = float(sys.argv[4]) if len(sys.argv) > 4 else 0.0
    first_frame_after = float(sys.argv[5]) if len(sys.argv) > 5 else 0.0
    rclpy.init(args=['--ros-args', '-r', f'__ns:={namespace}'])
    node = StandInCamera(encoding, scene, offset, first_frame_after)
    node.get_logger().info(f'streaming {encoding} {scene} at {FRAME_RATE_HZ:g} Hz, '
                           f'{time.strftime("%H:%M:%S")}')
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == '__main__':
    main()
