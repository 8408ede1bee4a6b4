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
lying on the platform; or, as the wide camera over a micro-factory, several robots each with
the code printed on it (robot_k carries code k), each where its own stand-in driver's
/robot_k/bench_truth/odom says. The grey frame becomes the sensor's encoding here, from the
encoding's definition (a Bayer pattern keeps one colour per pixel), under a warm light.

    python camera_driver.py NAMESPACE ENCODING SCENE [CLOCK_OFFSET_S [FIRST_FRAME_AFTER_S]]
    (SCENE: robot, chessboard, or robots=robot_0,robot_1 (the wide camera; robot_1@moving:
    that robot is no longer seen once it moves, as under a gripper's shadow); CLOCK_OFFSET_S:
    how far this machine's clock is off; FIRST_FRAME_AFTER_S: its device opens that long after
    the node, which streams nothing until then, as a driver waiting for its camera does)
"""

import collections
import functools
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
from omni_micro_vision.rendering import InView, Sensor, expose, render, render_robots
from omni_micro_vision.targets import Chessboard, render_target

# The camera: 1280 x 1024 pixels of 1.72 um on the platform, over the micro work platform,
# turned 0.5 rad, mirrored by a fold mirror, a lens bending its corners by 1 %.
CAMERA = CameraModel('bench', (0.1, 0.0), (1280 * 1.72e-6, 1024 * 1.72e-6), (1280, 1024))
OPTICS = CameraOptics(CAMERA, yaw_rad=0.5, mirrored=True, working_distance_m=0.006,
                      distortion=(-0.3, 0.1))
# The wide camera over several robots: 1280 x 1024 pixels of 117 um, square over the platform's
# left part, turned 0.02 rad, its lens bending the corners by 0.5 %.
WIDE_CAMERA = CameraModel('bench', (0.05, 0.0), (0.15, 0.12), (1280, 1024))
WIDE_OPTICS = CameraOptics(WIDE_CAMERA, yaw_rad=0.02, mirrored=False, working_distance_m=0.3,
                           distortion=(-0.05, 0.0))
FRAME_RATE_HZ = 15.0
DEVICE_BUFFERS = 4
# The line it prints for each frame it publishes, with the frame's stamp in nanoseconds.
SENT_FRAME = 'sent frame stamped'
TARGET = Chessboard((9, 6), 0.12e-3, (0.1001, 0.0), math.radians(10.0))
LIGHT = {'r': 1.0, 'g': 0.9, 'b': 0.7}


def to_encoding(grey: np.ndarray, encoding: str) -> np.ndarray:
    def channel(colour: str, window: np.ndarray) -> np.ndarray:
        return np.round(window * LIGHT[colour]).astype(np.uint8)

    if encoding == 'rgb8':
        return np.dstack([channel(colour, grey) for colour in 'rgb'])
    # A Bayer pattern keeps one colour per pixel: each colour is computed only where it is kept
    # (a quarter of the frame, a half for green), not over the whole frame and then dropped.
    pattern = encoding[len('bayer_'):len('bayer_') + 4]
    mosaic = np.empty_like(grey)
    for index, colour in enumerate(pattern):
        row, column = divmod(index, 2)
        mosaic[row::2, column::2] = channel(colour, grey[row::2, column::2])
    return mosaic


def state_at(states: collections.deque[tuple[int, RobotState]], at_ns: int) -> RobotState:
    """A robot's true state at ``at_ns``, between the two of its driver's ticks around it
    (its oldest kept, if ``at_ns`` is before it)."""
    before = states[0]
    for after in states:
        if after[0] >= at_ns:
            if after[0] == at_ns or after is before:
                return after[1]
            share = (at_ns - before[0]) / (after[0] - before[0])
            a, b = before[1], after[1]
            turn = math.remainder(b.phi_rad - a.phi_rad, math.tau)
            return RobotState(*(u + share * (v - u) for u, v in (
                (a.x_m, b.x_m), (a.y_m, b.y_m), (a.phi_rad, a.phi_rad + turn),
                (a.vx_m_s, b.vx_m_s), (a.vy_m_s, b.vy_m_s), (a.omega_rad_s, b.omega_rad_s))))
        before = after
    return states[-1][1]


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
        self.sensor = Sensor()
        self.target = (render_target(CAMERA, TARGET, OPTICS.yaw_rad)
                       if scene == 'chessboard' else None)
        # Each robot's recent true states with their stamps (two seconds of its driver's 50 Hz
        # ticks), by its code (the robot scene's one robot as 0).
        names = scene.partition('=')[2].split(',') if scene.startswith('robots=') else []
        self.robots: dict[int, collections.deque[tuple[int, RobotState]]] = {}
        self.hidden_once_moving = {int(name.split('@')[0].rpartition('_')[2])
                                   for name in names if name.endswith('@moving')}
        names = [name.split('@')[0] for name in names]
        self.optics = WIDE_OPTICS if names else OPTICS
        for name in names:
            self.create_subscription(Odometry, f'/{name}/bench_truth/odom', functools.partial(
                self.on_robot_truth, int(name.rpartition('_')[2])), 10)
        self.codes = len(names)
        self.hidden: set[int] = set()
        if not names:
            self.create_subscription(Odometry, '/bench_truth/odom',
                                     functools.partial(self.on_robot_truth, 0), 10)
        self.optics.prepare()
        self.frame = 0
        # The frames exposed that the host has not taken yet: a device's buffers (usb_cam maps
        # 4 by default).
        self.exposed: collections.deque[int] = collections.deque(maxlen=DEVICE_BUFFERS)
        self.create_timer(1.0 / FRAME_RATE_HZ, self.on_frame)

    def on_robot_truth(self, code: int, msg: Odometry) -> None:
        pose, twist = msg.pose.pose, msg.twist.twist
        phi = 2.0 * math.atan2(pose.orientation.z, pose.orientation.w)
        truth = RobotState(pose.position.x, pose.position.y, phi, twist.linear.x,
                           twist.linear.y, twist.angular.z)
        self.robots.setdefault(code, collections.deque(maxlen=100)).append(
            (msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec, truth))
        if code in self.hidden_once_moving and math.hypot(truth.vx_m_s, truth.vy_m_s) > 0:
            self.hidden_once_moving.discard(code)
            self.hidden.add(code)

    def on_frame(self) -> None:
        if time.monotonic() < self.device_open_at:
            return
        # Stamped when taken, by the system clock (on a machine whose clock may be off).
        if self.target is not None:
            self.send(self.get_clock().now().nanoseconds,
                      expose(self.target, self.sensor, np.random.default_rng([7, self.frame])))
        else:
            self.take_robots()

    def take_robots(self) -> None:
        """The camera exposes at its own rate whatever the robots' drivers are doing, every
        robot at one instant; a frame waits in the device's buffers until the host can take it
        (here: until every robot's truth has reached its time), the oldest overwritten when all
        are full. (Frames taken only as the truths came held every frame while one stand-in
        driver was starved of the CPU: 2 Hz sent, and the guard stopped robots it could not
        see. Each robot drawn at its own latest truth under the earliest's stamp showed a robot
        0.3 mm on between frames 2 ms apart by their stamps. A robot drawn at its latest truth
        but stamped when taken was shown where it had been: three such frames agreed, and the
        tracker called a moving robot still there.)"""
        self.exposed.append(self.get_clock().now().nanoseconds)
        if len(self.robots) < max(self.codes, 1):
            return
        known_ns = min(states[-1][0] for states in self.robots.values())
        while self.exposed and self.exposed[0] <= known_ns:
            taken_ns = self.exposed.popleft()
            rng = np.random.default_rng([7, self.frame])
            if not self.codes:
                self.send(taken_ns, render(CAMERA, self.sensor,
                                           state_at(self.robots[0], taken_ns), rng,
                                           OPTICS.yaw_rad))
                continue
            self.send(taken_ns, render_robots(
                WIDE_CAMERA, self.sensor,
                [InView(state_at(states, taken_ns), code) for code, states in
                 sorted(self.robots.items()) if code not in self.hidden],
                rng, WIDE_OPTICS.yaw_rad))

    def send(self, taken_ns: int, ideal: np.ndarray) -> None:
        """The frame taken at ``taken_ns`` (this machine's clock) and its CameraInfo."""
        self.frame += 1
        stamp = rclpy.time.Time(nanoseconds=taken_ns + self.clock_offset_ns).to_msg()
        samples = to_encoding(self.optics.view(ideal), self.encoding)
        image = Image(height=samples.shape[0], width=samples.shape[1], encoding=self.encoding,
                      is_bigendian=0, step=samples.strides[0])
        image.header.stamp = stamp
        image.header.frame_id = 'bench_optical_frame'
        image.data = samples.tobytes()
        lens = self.optics.lens
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
