"""The bench, with stand-ins built like real drivers (tests/bench): a camera driver that
publishes Bayer frames best effort, stamped with the wall clock, at its own resolution, pixel
size and mount, with a true CameraInfo; a robot whose driver reads /wheel_trajectory and
publishes /joint_states on the wall clock. The camera is calibrated from its own frames of a
chessboard (record, then calibrate-camera), and `run --camera external --robot external`
closes the loop; a camera whose clock is hours off ends the run at once, naming both clocks."""

import dataclasses
import json
import math
import runpy
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from nav_msgs.msg import Odometry

from omni_micro_bringup.processes import node_environment

pytestmark = pytest.mark.slow

BENCH = Path(__file__).resolve().parents[1] / 'bench'
ROOT = Path(__file__).resolve().parents[2]
# Where the stand-in camera's target lies (tests/bench/camera_driver.py, TARGET).
TARGET = ['--target-center-mm', '100.1,0', '--target-yaw-deg', '10', '--pitch-mm', '0.12']
GOAL_MM = (100.3, 0.2)


@pytest.fixture
def bench(domain_id, tmp_path):
    """``bench(script, *args)`` starts a stand-in in the test's domain; all are stopped with
    SIGINT afterwards, as a user stops a driver."""
    processes: list[tuple[subprocess.Popen, object]] = []

    def start(script: str, *args: str) -> subprocess.Popen:
        log = open(tmp_path / f'{script}-{len(processes)}.log', 'w')  # noqa: SIM115
        process = subprocess.Popen([sys.executable, str(BENCH / script), *args],
                                   env=node_environment(domain_id, tmp_path), stdout=log,
                                   stderr=subprocess.STDOUT)
        processes.append((process, log))
        return process

    yield start
    for process, _ in processes:
        process.send_signal(signal.SIGINT)
    for process, log in processes:
        try:
            process.wait(10)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
        log.close()  # type: ignore[attr-defined]


def stop(process: subprocess.Popen) -> None:
    process.send_signal(signal.SIGINT)
    process.wait(10)


def calibrate_the_standin_camera(bench, domain_id, tmp_path, omni_micro) -> Path:
    """As docs/images.md's bench procedure: the driver shows the target, a few seconds are
    recorded, calibrate-camera fits the camera (mirrored: the stand-in has a fold mirror)."""
    camera = bench('camera_driver.py', '/camera/micro', 'bayer_rggb8', 'chessboard')
    bag = tmp_path / 'target'
    recorder = subprocess.Popen(
        [str(ROOT / 'scripts' / 'omni-micro'), 'record', str(bag), '--topics',
         '/camera/micro/image_raw', '/camera/micro/camera_info', '--domain-id', str(domain_id)],
        env=node_environment(domain_id, tmp_path), stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, text=True)
    assert recorder.stdout is not None
    said = []
    try:
        for line in recorder.stdout:     # until it records (a first start may install first)
            said.append(line)
            if 'recording 2 topics' in line:
                break
        time.sleep(4.0)                  # a few seconds of the target, as a user would record
        recorder.send_signal(signal.SIGINT)
        said.append(recorder.communicate(timeout=60)[0])
    finally:
        if recorder.poll() is None:      # never left running, whatever failed above
            recorder.kill()
            recorder.wait()
    stop(camera)
    calibration = tmp_path / 'micro_calibration.yaml'
    fitted = omni_micro('calibrate-camera', str(bag), '--camera', 'micro', '--mirrored', *TARGET,
                        '--out', str(calibration))
    assert fitted.returncode == 0, fitted.stderr + ''.join(said)
    assert 'RMS residual' in fitted.stdout
    return calibration


def run_on_the_bench(omni_micro, domain_id, tmp_path, calibration, *extra):
    return omni_micro('run', '--goal-mm', f'{GOAL_MM[0]},{GOAL_MM[1]}', '--camera', 'external',
                      '--robot', 'external', '--domain-id', str(domain_id), '--params',
                      str(calibration), '--image-topic', 'micro=/bench/camera/image_raw',
                      '--log-dir', str(tmp_path / 'runs'), '--timeout', '60', '--json', *extra)


def test_the_loop_closes_with_a_standin_camera_and_robot_on_the_wall_clock(
        bench, domain_id, tmp_path, omni_micro, probe):
    calibration = calibrate_the_standin_camera(bench, domain_id, tmp_path, omni_micro)
    truth: list[Odometry] = []
    probe.node.create_subscription(Odometry, '/bench_truth/odom', truth.append, 10)
    bench('robot_driver.py', '0.1', '0.0', '0.0')
    bench('camera_driver.py', '/bench/camera', 'bayer_rggb8', 'robot')
    probe.spin_until(lambda: len(truth) > 5, 30.0, "the stand-in robot's truth")
    done = run_on_the_bench(omni_micro, domain_id, tmp_path, calibration)
    assert done.returncode == 0, done.stderr
    assert 'reached: last seen by the camera at' in done.stderr
    probe.spin_for(0.5)
    # Where the robot really is: within the controller's tolerance (3 um) of the goal, with the
    # calibration's own error beside it (the tracker states it; 0.1 um here).
    final = truth[-1].pose.pose.position
    assert math.hypot(final.x * 1e3 - GOAL_MM[0], final.y * 1e3 - GOAL_MM[1]) * 1e3 < 3.5
    # Nothing in the graph ran on simulated time: the captures were stamped by the camera.
    log = next((tmp_path / 'runs').glob('*/tracker_node.log')).read_text()
    assert 'mapped by its calibration' in log


def test_a_camera_on_a_clock_hours_off_ends_the_run_naming_both_clocks(
        bench, domain_id, tmp_path, omni_micro):
    # The stand-in camera's true map, as a calibration would find it (no need to fit one here).
    from omni_micro_vision.calibration import Calibration

    optics = runpy.run_path(str(BENCH / 'camera_driver.py'))['OPTICS']

    calibration = tmp_path / 'micro_calibration.yaml'
    calibration.write_text(Calibration(dataclasses.replace(optics.plane, name='micro'), 0, 0)
                           .params_yaml(mirrored=True))
    bench('robot_driver.py', '0.1', '0.0', '0.0')
    bench('camera_driver.py', '/bench/camera', 'bayer_rggb8', 'robot', '7200')
    started = time.monotonic()
    done = run_on_the_bench(omni_micro, domain_id, tmp_path, calibration)
    assert done.returncode == 1, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith('omni-micro run: failed: controller_node reported lost: a micro '
                           'capture is stamped ')
    assert '(the wall clock, ' in last and 'but the robot runs on ' in last
    assert 'the clocks differ by 2.00 h: synchronise the machines\' clocks' in last
    # At once: the first capture after the goal ends it (start-up and shut-down included).
    assert time.monotonic() - started < 30.0
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result['outcome'] == 'lost' and result['wall_time_s'] < 3.0
