"""`omni-micro bench-images`: what the rendered cameras and the tracker cost, per frame and in
the loop.

Per frame (in this process): render and track times of each camera at the default sizes, with
the robot still in the field, moving at cruise speed, and absent; the reference measured in the
same run is one draw of a frame's Gaussian noise with numpy (what a renderer that computed
every pixel would pay at least). In the loop: Fig. 11 through the node graph, lockstep at
--rtf max, with --vision images beside --vision model (the reference), idle and with one core
kept busy (the images runs must end at the same pose); and the size of the recorded images per
simulated second.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.machine_load import busy_cores
from omni_micro_cli.arguments import whole_number_in
from omni_micro_cli.outputs import print_json
from omni_micro_sim import paper
from omni_micro_tools.topics import IMAGE_TOPICS

if TYPE_CHECKING:
    from omni_micro_bringup.graph import GraphResult


# Where the robot is for each per-frame case: (camera, label, x, y, heading, speed along x).
FRAME_CASES = (('macro', 'robot still', 0.05, 0.01, 0.3, 0.0),
               ('macro', 'robot at 14 mm/s', 0.05, 0.01, 0.3, 0.014),
               ('micro', 'robot still', 0.1, 0.0, 0.3, 0.0),
               ('micro', 'robot at 14 mm/s', 0.1, 0.0, 0.3, 0.014),
               ('micro', 'robot outside', 0.09, 0.0, 0.3, 0.0))


def add_parser(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser(
        'bench-images',
        description='Time render and track per frame for each camera at the default sizes '
                    '(1280 x 1024, mono8), and what the tracker spends on a real camera\'s '
                    '2448 x 2048 frames at 30 Hz (mono8 and Bayer) beside the frame period, '
                    'then run Fig. 11 through the node graph with '
                    '--vision images and --vision model (lockstep, --rtf max; idle, and images '
                    'with one core busy), and record a short run with its images for their '
                    'size per simulated second. Target: rtf >= 5 with images on this 2-core '
                    'machine.')
    parser.add_argument('--frames',
                        type=whole_number_in(1, 10_000), default=50, metavar='N',
                        help='frames timed per case (default 50)')
    parser.add_argument('--no-graph', dest='graph', action='store_false',
                        help='only the per-frame timings')
    parser.add_argument('--json', action='store_true',
                        help='standard output: one JSON object alone (the rest on stderr)')
    parser.set_defaults(handler=run)


def _median_ms(action: Callable[[int], object], count: int) -> float:
    action(count)   # caches (the flat fields) and imports are not what a frame costs
    times = []
    for index in range(count):
        started = time.perf_counter()
        action(index)
        times.append(time.perf_counter() - started)
    return 1e3 * float(np.median(times))


def frame_costs(frames: int) -> list[dict[str, object]]:
    from omni_micro_sim.state import RobotState
    from omni_micro_vision.camera import DEFAULT_RIG, CameraModel
    from omni_micro_vision.geometry import PlaneMap
    from omni_micro_vision.rendering import Sensor, render
    from omni_micro_vision.tracking import track

    sensor = Sensor()
    rows = []
    for name, label, x, y, heading, speed in FRAME_CASES:
        camera = getattr(DEFAULT_RIG, name)
        plane = PlaneMap.nominal(camera)
        state = RobotState(x, y, heading, speed, 0.0, 0.0)
        images = [render(camera, sensor, state, np.random.default_rng([1, i]))
                  for i in range(frames + 1)]
        shape = images[0].shape

        def draw_frame(index: int, camera: CameraModel = camera,
                       state: RobotState = state) -> object:
            return render(camera, sensor, state, np.random.default_rng([2, index]))

        def track_frame(index: int, plane: PlaneMap = plane,
                        images: list[np.ndarray] = images) -> object:
            return track(images[index], plane)

        def track_near(index: int, plane: PlaneMap = plane,
                       images: list[np.ndarray] = images,
                       near: tuple[float, float] = (x, y)) -> object:
            return track(images[index], plane, near=near)

        def draw_noise(index: int, shape: tuple[int, ...] = shape) -> object:
            return np.random.default_rng(index).standard_normal(shape, dtype=np.float32)

        render_ms = _median_ms(draw_frame, frames)
        track_ms = _median_ms(track_frame, frames)
        near_ms = _median_ms(track_near, frames)
        noise_ms = _median_ms(draw_noise, frames)
        found = track(images[0], plane).found
        rows.append({'camera': name, 'case': label, 'render_ms': round(render_ms, 2),
                     'track_ms': round(track_ms, 2), 'track_near_last_pose_ms': round(near_ms, 2),
                     'noise_draw_ms': round(noise_ms, 2),
                     'render_vs_noise_draw': round(render_ms / noise_ms, 2), 'found': found})
        print(f'{name:5s} {label:17s} render {render_ms:6.2f} ms ({render_ms / noise_ms:4.2f} x '
              f'one full-frame noise draw, {noise_ms:.2f} ms)  track {track_ms:5.2f} ms, near '
              f'the last pose {near_ms:5.2f} ms  fiducial {"found" if found else "absent"}',
              flush=True)
    return rows


# A real camera's large frames, as its driver sends them (the micro field at 1 um a pixel).
DRIVER_RESOLUTION = (2448, 2048)
DRIVER_RATE_HZ = 30.0
DRIVER_ENCODINGS = ('mono8', 'bayer_rggb8')


def driver_frame_costs(frames: int) -> list[dict[str, object]]:
    """What tracker_node spends on each of a real camera's frames: its encoding made grey
    (image_array) and the fiducial found near the last pose, beside the frame period."""
    from sensor_msgs.msg import Image

    from omni_micro_sim.state import RobotState
    from omni_micro_vision.camera import CameraModel
    from omni_micro_vision.geometry import PlaneMap
    from omni_micro_vision.image_messages import image_array
    from omni_micro_vision.rendering import Sensor, render
    from omni_micro_vision.tracking import FrameTracker

    columns, rows_px = DRIVER_RESOLUTION
    camera = CameraModel('micro', (0.1, 0.0), (columns * 1e-6, rows_px * 1e-6),
                         DRIVER_RESOLUTION)
    plane = PlaneMap.nominal(camera)
    grey = [render(camera, Sensor(), RobotState(0.1002, 0.0001, 0.3),
                   np.random.default_rng([3, i])) for i in range(4)]
    period_ms = 1e3 / DRIVER_RATE_HZ
    rows = []
    for encoding in DRIVER_ENCODINGS:
        messages = []
        for pixels in grey:
            if encoding.startswith('bayer'):
                # The pattern's definition: each pixel keeps one colour (here of a grey scene).
                pixels = pixels.copy()
                pixels[0::2, 1::2] = (pixels[0::2, 1::2] * 0.9).astype(np.uint8)
                pixels[1::2, 1::2] = (pixels[1::2, 1::2] * 0.7).astype(np.uint8)
            messages.append(Image(height=rows_px, width=columns, encoding=encoding,
                                  step=columns, data=pixels.tobytes()))
        tracker = FrameTracker(plane)

        def read_frame(index: int, messages: list[Image] = messages,
                       tracker: FrameTracker = tracker) -> object:
            found = tracker(image_array(messages[index % len(messages)], DRIVER_RESOLUTION))
            assert found.found, found.reason
            return found

        cost_ms = _median_ms(read_frame, frames)
        rows.append({'encoding': encoding, 'resolution': list(DRIVER_RESOLUTION),
                     'per_frame_ms': round(cost_ms, 2),
                     'of_frame_period': round(cost_ms / period_ms, 3)})
        print(f'{columns} x {rows_px} {encoding:12s} read and track {cost_ms:6.2f} ms a frame: '
              f'{cost_ms / period_ms:.2f} of the {DRIVER_RATE_HZ:g} Hz period '
              f'({"keeps up" if cost_ms < period_ms else "falls behind"})', flush=True)
    return rows


def _fig11(vision: str, busy: int, scratch: Path, composed: bool = False) -> GraphResult:
    from omni_micro_bringup.graph import run_graph

    with busy_cores(busy):
        return run_graph(GraphOptions(
            goal_m=paper.FIG11_GOAL_M, real_time_factor=math.inf, log_dir=scratch / 'logs',
            timeout_s=300.0, vision=vision, markers=False, composed=composed))


def loop_costs(scratch: Path) -> dict[str, object]:
    from omni_micro_bringup.graph import run_graph
    from omni_micro_tools.bag_reading import read_bag

    rows = []
    for label, vision, busy, composed in (('model, idle (reference)', 'model', 0, False),
                                          ('images, idle', 'images', 0, False),
                                          ('images, 1 core busy', 'images', 1, False),
                                          ('images --composed, idle', 'images', 0, True)):
        result = _fig11(vision, busy, scratch, composed)
        rtf = result.sim_time_s / result.wall_time_s
        rows.append({'case': label, 'outcome': result.outcome, 'rtf_reached': round(rtf, 2),
                     'sim_time_s': round(result.sim_time_s, 3), 'periods': result.periods,
                     'deviation_um': round(result.deviation_m * 1e6, 3)})
        print(f'Fig. 11 --vision {label:24s} {result.outcome:8s} rtf {rtf:5.2f}  '
              f'{result.sim_time_s:6.2f} s sim in {result.wall_time_s:5.2f} s wall, '
              f'{result.periods} periods, {result.deviation_m * 1e6:.3f} um from the goal',
              flush=True)
    model, idle = float(rows[0]['rtf_reached']), float(rows[1]['rtf_reached'])  # type: ignore[arg-type]
    same = rows[1]['sim_time_s'] == rows[2]['sim_time_s'] \
        and rows[1]['deviation_um'] == rows[2]['deviation_um']
    composed_rtf = rows[3]['rtf_reached']
    print(f'images / model rtf: {idle / model:.2f} (images rtf {idle}, --composed '
          f'{composed_rtf}, target >= 5); images runs idle and busy identical: {same}',
          flush=True)
    bag = scratch / 'images-bag'
    recorded = run_graph(GraphOptions(
        goal_m=(0.1005, 0.0004), real_time_factor=math.inf, log_dir=scratch / 'logs',
        vision='images', record=bag, record_images=True, markers=False,
        dynamics_overrides={'initial_pose': [0.1, 0.0, 0.0]}))
    # Per frame time from the bag's own messages (the recorder runs on past the outcome).
    streams = read_bag(bag, topics=list(IMAGE_TOPICS), decode=False)
    frames = len(streams.raw['/camera/macro/image_raw'])
    frame_bytes = sum(len(raw) for topic in streams.raw for raw in streams.raw[topic]) / frames
    rate_hz = 30.0
    per_second = frame_bytes * rate_hz / 1e6
    folder_mb = sum(f.stat().st_size for f in bag.iterdir()) / 1e6
    print(f'recorded with --record-images: {frames} frames of each camera, '
          f'{frame_bytes / 1e6:.2f} MB per frame pair (images and camera infos): '
          f'{per_second:.0f} MB per simulated second at {rate_hz:g} Hz (bag folder '
          f'{folder_mb:.0f} MB, {recorded.outcome} after {recorded.sim_time_s:.2f} s)',
          flush=True)
    return {'runs': rows, 'images_over_model_rtf': round(idle / model, 2),
            'images_composed_rtf': composed_rtf,
            'images_identical_idle_busy': same, 'bag_mb_per_sim_s': round(per_second, 1)}


def run(args: argparse.Namespace) -> int:
    report: dict[str, object] = {'frames': frame_costs(args.frames),
                                 'driver_frames': driver_frame_costs(args.frames)}
    if args.graph:
        with tempfile.TemporaryDirectory(prefix='omni-micro-bench-images-') as folder:
            report['loop'] = loop_costs(Path(folder))
    if args.json:
        print_json(report)
    return 0
