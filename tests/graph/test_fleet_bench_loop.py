"""Several real robots on the bench, with stand-ins built like real drivers (tests/bench): two
robot drivers, each in its namespace (``/robot_k/joint_states`` out, ``/robot_k/wheel_trajectory``
in, on the wall clock), and one wide camera driver showing both with the codes printed on them.
`run --robots FILE --camera external --robot external` drives both to their goals whichever
driver comes up first, and stops both, naming them, when two are driven at each other.

``OMNI_MICRO_BENCH_REPEATS=20 ./scripts/test tests/graph/test_fleet_bench_loop.py`` runs each start
order, and the pair driven at each other, that many times (docs/fleet.md quotes the counts)."""

import dataclasses
import json
import math
import os
import runpy
import signal
import subprocess
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from nav_msgs.msg import Odometry

from omni_micro_bringup.processes import node_environment

pytestmark = pytest.mark.slow
ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / 'tests' / 'bench'
REPEATS = int(os.environ.get('OMNI_MICRO_BENCH_REPEATS', '1'))
# Two robots 30 mm apart, each sent 25 mm along +x: lanes the planner keeps apart.
STARTS_MM = ((20.0, 0.0), (20.0, 30.0))
GOALS_MM = ((45.0, 0.0), (45.0, 30.0))
TOLERANCE_UM = 300.0     # a wide camera's: 117 um pixels


def wide_calibration(tmp_path: Path) -> Path:
    """The wide stand-in camera's true map, as calibrate-camera finds it (tested in
    test_bench_loop for the micro one)."""
    from omni_micro_vision.calibration import Calibration

    optics = runpy.run_path(str(BENCH / 'camera_driver.py'))['WIDE_OPTICS']
    path = tmp_path / 'macro_calibration.yaml'
    path.write_text(Calibration(dataclasses.replace(optics.plane, name='macro'), 0, 0)
                    .params_yaml(mirrored=False))
    return path


def fleet_files(tmp_path: Path, goals_mm=GOALS_MM) -> tuple[Path, Path]:
    """The robots at STARTS_MM; ``goals_mm``: each robot's goal, or its goals (a list)."""
    robots = tmp_path / 'robots.yaml'
    robots.write_text('robots:\n' + ''.join(
        f'  - start_mm: [{x}, {y}]\n    wheel_offsets_deg: [0, 0, 0]\n' for x, y in STARTS_MM))
    tasks = tmp_path / 'tasks.yaml'
    goals = [robot if isinstance(robot, list) else [robot] for robot in goals_mm]
    tasks.write_text('tasks:\n' + ''.join(
        f'  robot_{k}:\n' + ''.join(f'    - goal_mm: [{x}, {y}]\n      tolerance_um: '
                                     f'{TOLERANCE_UM}\n' for x, y in own)
        for k, own in enumerate(goals) if own != [STARTS_MM[k]]))
    return robots, tasks


def bench_run(domain_id: int, tmp_path: Path, *extra: str, goals_mm=GOALS_MM,
              door: tuple[str, ...] = ('run', '--timeout', '120')) -> subprocess.Popen:
    """The run on the bench through ``door`` (``run``, or ``fleet --graph``: the same run)."""
    robots, tasks = fleet_files(tmp_path, goals_mm)
    return subprocess.Popen(
        [str(ROOT / 'scripts' / 'omni-micro'), *door, '--robots', str(robots), '--tasks',
         str(tasks), '--camera', 'external', '--robot', 'external', '--domain-id',
         str(domain_id), '--params', str(wide_calibration(tmp_path)), '--image-topic',
         'macro=/bench/camera/image_raw', '--log-dir', str(tmp_path / 'runs'), '--json', *extra],
        env=node_environment(domain_id, tmp_path), stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True)


def start_robot(bench, k: int, first_after_s: float = 0.0) -> None:
    x, y = STARTS_MM[k]
    bench('robot_driver.py', str(x * 1e-3), str(y * 1e-3), '0.0', str(first_after_s),
          f'/robot_{k}')


def start_camera(bench, first_after_s: float = 0.0, robots: str = 'robot_0,robot_1') -> None:
    bench('camera_driver.py', '/bench/camera', 'bayer_rggb8', f'robots={robots}', '0',
          str(first_after_s))


def truths(probe) -> list[list[Odometry]]:
    seen: list[list[Odometry]] = [[], []]
    for k in range(2):
        probe.node.create_subscription(Odometry, f'/robot_{k}/bench_truth/odom',
                                       seen[k].append, 10)
    return seen


def finished(run: subprocess.Popen, timeout_s: float) -> tuple[str, str]:
    try:
        return run.communicate(timeout=timeout_s)
    finally:
        if run.poll() is None:
            run.send_signal(signal.SIGINT)
            run.communicate(timeout=30)


# Who starts when, the run first (it waits for every driver): "robot_1 late", its hardware a
# second after its node; "camera late", its device open 3.5 s after its node.
STARTS = {'camera first': (('camera', 0.0), ('robot_0', 0.0), ('robot_1', 0.0)),
          'robots first': (('robot_1', 0.0), ('robot_0', 0.0), ('camera', 0.0)),
          'robot_1 late': (('robot_0', 0.0), ('camera', 0.0), ('robot_1', 1.0)),
          'camera late': (('robot_0', 0.0), ('robot_1', 0.0), ('camera', 3.5))}


@pytest.mark.parametrize('repeat', range(REPEATS))
@pytest.mark.parametrize('start', list(STARTS))
def test_two_robots_reach_their_goals_in_any_start_order(bench, domain_id, tmp_path, probe,
                                                         start, repeat):
    truth = truths(probe)
    run = bench_run(domain_id, tmp_path)
    for index, (driver, first_after) in enumerate(STARTS[start]):
        if index:
            time.sleep(1.0)   # a second apart, in this order
        if driver == 'camera':
            start_camera(bench, first_after)
        else:
            start_robot(bench, int(driver[-1]), first_after)
    out, err = finished(run, 150)
    assert run.returncode == 0, err
    summary = json.loads(out)
    assert summary['outcome'] == 'done', err
    probe.spin_until(lambda: all(truth), 10.0, "the stand-in robots' truth")
    probe.spin_for(0.3)
    for k, goal in enumerate(GOALS_MM):
        final = truth[k][-1].pose.pose.position
        # Where each robot really is: within its tolerance of its goal.
        assert math.dist((final.x * 1e3, final.y * 1e3), goal) * 1e3 < TOLERANCE_UM, err
    assert '[orchestration] waiting for ' in err and 'the cameras name robot_0, robot_1' in err
    print(f'{start}: both goals reached, the last at {summary["sim_time_s"]:.1f} s on the wall '
          'clock')


def jogger(probe, robot: int) -> Callable[[float, float], None]:
    """A hand on the robot's command topic (as ``ros2 topic pub`` would): ``jog(steering_rad,
    duration_s)`` sends a move along ``steering_rad`` at cruise for ``duration_s``, starting
    now. Its writer is made at once, to be matched by the robot's driver before it is needed:
    made at the jog, its discovery beside busy processes eats into the seconds the robot's
    controller waits for a capture before it gives the robot up (the likely cause of a run
    that ended lost where the guard should have stopped it, once, beside two other graphs)."""
    from builtin_interfaces.msg import Duration
    from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

    from omni_micro_common.conventions import JOINT_NAMES, split_stamp
    from omni_micro_sim.profile import move_profile
    from omni_micro_sim.wheel_trajectory import points_from_profile

    publisher = probe.node.create_publisher(JointTrajectory, f'/robot_{robot}/wheel_trajectory',
                                            10)

    def jog(steering_rad: float, duration_s: float) -> None:
        command = JointTrajectory(joint_names=list(JOINT_NAMES))
        for point in points_from_profile(steering_rad, move_profile(duration_s)):
            sec, nanosec = split_stamp(point.time_from_start_s)
            command.points.append(JointTrajectoryPoint(
                positions=list(point.positions), velocities=list(point.velocities),
                time_from_start=Duration(sec=sec, nanosec=nanosec)))
        probe.spin_until(lambda: driver_matched(probe, publisher), 10.0, 'its driver')
        publisher.publish(command)
    return jog


def wait_until_moving(probe, robot: int) -> None:
    """Until robot ``robot``'s controller says it moves (its status, latched as a ROS tool
    would read it): its goal under way. Not its goal on /robot_k/goal_pose, nor its driver's
    truth: the coordinator hands a goal out once the robot's controller has it, and a move of
    the paper's rule lasts a fifth of a second; a probe that discovered either writer late
    missed both (a run then ended lost, never jogged)."""
    from diagnostic_msgs.msg import DiagnosticStatus

    from omni_micro_common.qos import STATUS_QOS

    said: list[str] = []
    probe.node.create_subscription(DiagnosticStatus, f'/robot_{robot}/controller/status',
                                   lambda msg: said.append(msg.message), STATUS_QOS)
    probe.spin_until(lambda: 'moving' in said, 90.0, f"robot_{robot}'s controller moving")


def driver_matched(probe, publisher) -> bool:
    """Whether the stand-in driver reads the topic and ``publisher`` has matched every reader
    there is: any reader would do for a count, and the recorder's, matched first, once let a jog
    go out before the driver's (volatile: the robot never moved)."""
    readers = probe.node.get_subscriptions_info_by_topic(publisher.topic_name)
    return any(info.node_name == 'standin_robot_driver' for info in readers) and \
        publisher.get_subscription_count() >= len(readers)


def closest_mm(truth: list[list[Odometry]]) -> float:
    """The closest the two stand-in robots' true centres came, at the first's states."""
    def at(msg: Odometry) -> tuple[int, float, float]:
        stamp = msg.header.stamp
        return (stamp.sec * 10**9 + stamp.nanosec, msg.pose.pose.position.x,
                msg.pose.pose.position.y)

    other = [at(msg) for msg in truth[1]]
    closest = math.inf
    for t, x, y in (at(msg) for msg in truth[0]):
        near = min(other, key=lambda sample: abs(sample[0] - t))
        if abs(near[0] - t) <= 20_000_000:
            closest = min(closest, math.dist((x, y), near[1:]) * 1e3)
    return closest


@pytest.mark.parametrize('repeat', range(REPEATS))
def test_two_robots_driven_at_each_other_are_both_stopped_before_contact_and_named(
        bench, domain_id, tmp_path, probe, repeat):
    """Robot 0 is sent toward robot 1 (a goal 15 mm short of it, then back) while robot 1,
    parked, is jogged by hand straight at robot 0: no planner keeps them apart. The guard stops
    both, names them, and the bench log keeps it; neither moves again."""
    from geometry_msgs.msg import PoseStamped

    truth = truths(probe)
    jog = jogger(probe, 1)
    goals: list[PoseStamped] = []
    probe.node.create_subscription(PoseStamped, '/robot_0/goal_pose', goals.append, 10)
    bag = tmp_path / 'bench_log'
    run = bench_run(domain_id, tmp_path, '--record', str(bag),
                    goals_mm=([(20.0, 15.0), STARTS_MM[0]], STARTS_MM[1]))
    start_camera(bench)
    start_robot(bench, 0)
    start_robot(bench, 1)
    probe.spin_until(lambda: bool(goals), 90.0, "robot_0's goal")
    jog(-math.pi / 2, 2.0)
    last = stopped(run, 'robot_0 and robot_1 ')
    assert 'closing at' in last and 'under 10 mm within ' in last
    # At rest a second on (no move after the stop), and never closer than the discs allow.
    assert_at_rest(probe, truth)
    closest = closest_mm(truth)
    assert closest > 9.0, f'the discs touched: centres {closest:.2f} mm apart; {last}'
    print(f'stopped: {last}; the closest the centres came: {closest:.2f} mm')
    check_the_stop_in_the_bench_log(bag)


def test_a_robot_driving_unseen_stops_every_robot_naming_it(bench, domain_id, tmp_path, probe):
    """Robot 1, sent to its goal, is no longer seen by the camera once it moves (a shadow over
    it), and is jogged on by hand: once its wheels have turned unnamed for the bound (1 s),
    every robot is stopped, robot 1 named."""
    truth = truths(probe)
    jog = jogger(probe, 1)
    run = bench_run(domain_id, tmp_path, goals_mm=(STARTS_MM[0], GOALS_MM[1]))
    start_camera(bench, robots='robot_0,robot_1@moving')
    start_robot(bench, 0)
    start_robot(bench, 1)
    wait_until_moving(probe, 1)
    jog(0.0, 2.5)
    last = stopped(run, 'robot_1 drove unnamed by the cameras for 1.0')
    assert 'last named at (20.0, 30.0) mm' in last
    assert_at_rest(probe, truth)


def test_a_robot_standing_unseen_is_left_to_its_controller(bench, domain_id, tmp_path, probe):
    """Robot 1, unseen once it has moved, stands still waiting for a capture (the paper's rule
    moves, then looks): no danger, so the guard leaves it to its controller, which gives up on
    it as a single robot's does (lost); nobody was stopped."""
    truth = truths(probe)
    run = bench_run(domain_id, tmp_path, goals_mm=(STARTS_MM[0], GOALS_MM[1]))
    start_camera(bench, robots='robot_0,robot_1@moving')
    start_robot(bench, 0)
    start_robot(bench, 1)
    out, err = finished(run, 90)
    assert run.returncode == 1, err
    assert json.loads(out)['outcome'] == 'lost', err
    last = err.strip().splitlines()[-1]
    assert last.startswith('omni-micro run: failed: lost: robot 1 lost: no capture'), err
    assert 'every robot stopped' not in err
    assert_at_rest(probe, truth)


def stopped(run: subprocess.Popen, why: str) -> str:
    """The run's last line, once it has ended stopped by the guard for ``why`` (its start)."""
    out, err = finished(run, 90)
    assert run.returncode == 1, err
    assert json.loads(out)['outcome'] == 'stopped', err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f'omni-micro run: failed: stopped: every robot stopped: {why}'), err
    return last


def assert_at_rest(probe, truth: list[list[Odometry]]) -> None:
    """Both stand-in robots still a second on: no move after the stop."""
    probe.spin_for(1.0)
    for k in range(2):
        twist = truth[k][-1].twist.twist.linear
        assert math.hypot(twist.x, twist.y) < 1e-6


def test_a_robot_not_where_the_robots_file_says_is_refused_before_any_goal(
        bench, domain_id, tmp_path):
    """Robot 1 stands 3 mm from its start in the robots file: the plan would be wrong, so no
    goal is handed out, and the line says where it is (through fleet --graph, the other door
    to the same run)."""
    run = bench_run(domain_id, tmp_path, door=('fleet', '--graph'))
    start_camera(bench)
    start_robot(bench, 0)
    x, y = STARTS_MM[1]
    bench('robot_driver.py', str(x * 1e-3), str((y + 3.0) * 1e-3), '0.0', '0', '/robot_1')
    _out, err = finished(run, 90)
    assert run.returncode == 2, err
    last = err.strip().splitlines()[-1]
    assert last.startswith('omni-micro fleet: error: robot_1 stands at (20.0'), err
    assert "from its start (20, 30) mm in the robots file: the plan starts from the file's " \
        "places; give each robot's start_mm where it stands" in last
    # No controller took a goal (each logs every goal it takes): read from their logs, not
    # from a probe's reader, which could have matched the coordinator's writer too late.
    (logs,) = (tmp_path / 'runs').iterdir()
    controllers = sorted(logs.glob('robot_*.controller_node.log'))
    assert len(controllers) == 2
    for log in controllers:
        text = log.read_text()
        assert 'controller ready' in text and 'goal (' not in text, text


def check_the_stop_in_the_bench_log(bag: Path) -> None:
    """The bag keeps each robot's wheels and commands, the stop sent to each, why, and the
    goal under way cancelled."""
    from omni_micro_tools.bag_reading import read_bag

    data = read_bag(bag)
    topics = set(data.timestamps)
    for k in range(2):
        assert {f'/robot_{k}/joint_states', f'/robot_{k}/wheel_trajectory'} <= topics
        commands = data.messages[f'/robot_{k}/wheel_trajectory']
        assert not commands[-1].points, 'the last command to each robot is the stop'
        # The guard's stop in the robot's own base frame, as its controller's moves are (robot 1's
        # jog is the test's hand, in no frame).
        assert commands[-1].header.frame_id == f'robot_{k}/base_link'
    assert {command.header.frame_id for command in data.messages['/robot_0/wheel_trajectory']} \
        == {'robot_0/base_link'}
    said = data.messages['/fleet_guard']
    assert len(said) == 1 and said[0].message.startswith('robot_0 and robot_1 ')
    values = {item.key: item.value for item in said[0].values}
    assert values == {'kind': 'proximity', 'robots': 'robot_0,robot_1',
                      'stopped': 'robot_0,robot_1'}
    # robot_0's controller, driving at robot_1 when the guard stopped both, is told: its goal
    # ends cancelled, not reached where the robot was stopped.
    statuses = [data.messages[f'/robot_{k}/controller/status'] for k in range(2)]
    last = statuses[0][-1]
    assert last.message == 'cancelled', [status.message for status in statuses[0]]
    assert {v.key: v.value for v in last.values}['reason'] == 'cancelled on request'
    assert [status.message for status in statuses[1]] == ['idle']   # parked, jogged by hand
