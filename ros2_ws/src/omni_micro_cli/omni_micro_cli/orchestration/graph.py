"""Orchestration of the node graph (what a launch file would do, launch being unavailable here).

Starts each node as its own OS process through its installed entry point, with its package's
params file, on loopback only and in a private DDS domain; keeps and prefixes their logs; brings
the graph up with the clock paused so that nothing moves before every node listens; waits for the
controller's outcome; shuts down in phases (the controller, then the rest at once, then the
recorder; SIGINT, and SIGTERM / SIGKILL only for a node that hangs) and cleans Fast DDS
shared-memory leftovers.

The children cannot outlive it: each inherits the read end of a lifeline pipe whose write end
only this process holds (when it dies, however it dies, every node reads end-of-file and stops),
and the lock file of the run's DDS domain, so that the domain is not handed to another run while
any process of this one is still in it.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TextIO

from omni_micro_cli.errors import RunFailed, UsageError
from omni_micro_common.conventions import GRAPH_NODE_NAMES, LIFELINE_ENV, PUBLISHED_MARKER

# Stopped phase by phase, each phase at once: the controller first (its stop command is its last
# word), the recorder last (it keeps the stop and the final samples); anyone else in between.
SHUTDOWN_PHASES = (('controller_node',), None, ('bag_recorder',))
# Nodes that report to the dynamics in lockstep (a stand-in started by command does not).
LOCKSTEP_NODES = ('vision_node', 'camera_node', 'tracker_node', 'controller_node')
# What stands for the cameras: vision_node's measurement model, or rendered images and the
# tracker that turns them into captures (what a real camera and its tracker would do).
VISION_MODES = {'model': (('omni_micro_vision', 'vision_node'),),
                'images': (('omni_micro_vision', 'camera_node'),
                           ('omni_micro_vision', 'tracker_node'))}
# Fast DDS: domain ids above 232 do not fit its port scheme.
DOMAIN_RANGE = range(1, 232)


@dataclass(frozen=True)
class NodeSpec:
    """One node process: its package, executable and parameter overrides."""

    package: str
    executable: str
    overrides: dict[str, object] = field(default_factory=dict)
    # A command line that replaces the installed entry point (e.g. a stand-in camera driver).
    command: tuple[str, ...] | None = None
    respawn: bool = False
    # A command that reports on /lockstep all the same (the recorder keeping every frame).
    lockstep: bool = False

    @property
    def name(self) -> str:
        return self.executable

    @property
    def reports_lockstep(self) -> bool:
        return self.lockstep or (self.command is None and self.executable in LOCKSTEP_NODES)


def default_nodes(vision: str = 'model') -> list[NodeSpec]:
    if vision not in VISION_MODES:
        raise UsageError(f'vision must be one of {sorted(VISION_MODES)}, got {vision!r}')
    dynamics, _, controller = GRAPH_NODE_NAMES
    return [NodeSpec('omni_micro_sim', dynamics),
            *(NodeSpec(package, name) for package, name in VISION_MODES[vision]),
            NodeSpec('omni_micro_control', controller)]


def message_class(msgtype: str) -> type:
    """The rclpy message class of 'pkg/msg/Name' (rosidl_runtime_py is not installable here)."""
    import importlib

    package, _, name = msgtype.split('/')
    return getattr(importlib.import_module(f'{package}.msg'), name)


def recorder_spec(bag: Path, storage: str, markers: bool = True,
                  images: tuple[str, ...] = (), without: tuple[str, ...] = ()) -> NodeSpec:
    """The recorder of a run; with ``images`` (cameras) their image streams too, and then it
    takes part in the lockstep so that no frame is lost to a slow disk. ``without``: topics
    nobody in this graph publishes (it waits for a publisher of each before the clock starts)."""
    from omni_micro_tools.bags import GRAPH_TOPICS, MARKERS_TOPIC

    topics = [topic for topic in GRAPH_TOPICS
              if (markers or topic != MARKERS_TOPIC) and topic not in without]
    topics += [f'/camera/{camera}/{stream}' for camera in images
               for stream in ('image_raw', 'camera_info')]
    return NodeSpec('omni_micro_cli', 'bag_recorder', command=(
        sys.executable, '-m', 'omni_micro_cli', 'record', str(bag), '--storage', storage,
        '--topics', *topics, *(('--lockstep-frames',) if images else ())),
        lockstep=bool(images))


def viewer_spec(host: str, port: int, markers: bool) -> NodeSpec:
    return NodeSpec('omni_micro_cli', 'viewer', command=(
        sys.executable, '-m', 'omni_micro_cli', 'view', '--view-host', host, '--view-port',
        str(port), *(() if markers else ('--no-markers',))))


MARKERS_NODE = NodeSpec('omni_micro_vision', 'markers_node')
# What markers_node must draw as the other nodes see it: their parameters, passed on.
MARKERS_FROM_VISION = ('macro.center_m', 'macro.field_m', 'macro.yaw_rad', 'micro.center_m',
                       'micro.field_m', 'micro.yaw_rad')


def install_prefixes() -> list[Path]:
    prefixes = os.environ.get('AMENT_PREFIX_PATH', sys.prefix).split(os.pathsep)
    return [Path(p) for p in prefixes if p]


def resolve_executable(package: str, executable: str) -> Path:
    """Where ``ros2 run package executable`` would find it: <prefix>/lib/<package>/<exe>, or the
    venv's bin/ where pip puts console scripts."""
    for prefix in install_prefixes():
        for candidate in (prefix / 'lib' / package / executable, prefix / 'bin' / executable):
            if candidate.is_file() and os.access(candidate, os.X_OK):
                return candidate
    raise RunFailed(f'{package}/{executable} is not installed under '
                    f'{[str(p) for p in install_prefixes()]} (run ./scripts/test once to install)')


def package_params_file(package: str, executable: str) -> Path:
    for prefix in install_prefixes():
        path = prefix / 'share' / package / 'config' / f'{executable}.yaml'
        if path.is_file():
            return path
    raise RunFailed(f'params file config/{executable}.yaml of {package} is not installed')


def format_parameter(value: object) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return ('.inf' if value > 0 else '-.inf') if math.isinf(value) else repr(value)
    if isinstance(value, (list, tuple)):
        return '[' + ','.join(format_parameter(v) for v in value) + ']'
    return str(value)


def check_params_file(path: Path) -> None:
    """Refuse a params file that would make a node die at start-up: say what is wrong with it."""
    import yaml

    if not path.is_file():
        raise UsageError(f'params file {str(path)!r} does not exist')
    try:
        content = yaml.safe_load(path.read_text())
    except yaml.YAMLError as error:
        raise UsageError(f'params file {str(path)!r} does not parse as YAML: {error}') from None
    if not isinstance(content, dict) or not all(
            isinstance(section, dict) and 'ros__parameters' in section
            for section in content.values()):
        raise UsageError(
            f'params file {str(path)!r} must map node names to {{ros__parameters: {{...}}}}, '
            f'got {content!r:.200}')


class DomainLease:
    """A ROS_DOMAIN_ID no other omni-micro run on this machine holds (an flock per id)."""

    def __init__(self, requested: int | None = None) -> None:
        self.requested = requested
        self.domain_id: int | None = None
        self._file: TextIO | None = None

    def __enter__(self) -> int:
        folder = Path(tempfile.gettempdir()) / f'omni-micro-domains-{os.getuid()}'
        folder.mkdir(exist_ok=True)
        candidates = ([self.requested] if self.requested is not None
                      else random.sample(list(DOMAIN_RANGE), len(DOMAIN_RANGE)))
        for candidate in candidates:
            handle = open(folder / f'{candidate}.lock', 'w')
            try:
                fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                handle.close()
                continue
            self._file, self.domain_id = handle, candidate
            return candidate
        raise RunFailed(f'no free ROS_DOMAIN_ID among {candidates[:5]}...')

    @property
    def fileno(self) -> int:
        """The locked file: a child that inherits it holds the lease until it exits too."""
        assert self._file is not None, 'the lease is not held'
        return self._file.fileno()

    def __exit__(self, *exc: object) -> None:
        if self._file is not None:
            self._file.close()


class NodeProcess:
    """A node's OS process, with its output kept in a log file and echoed with a prefix."""

    def __init__(self, spec: NodeSpec, argv: list[str], env: dict[str, str], log_path: Path,
                 echo: Callable[[str], None] | None, inherited_fds: tuple[int, ...] = ()) -> None:
        self.spec = spec
        self.inherited_fds = inherited_fds
        self.argv = argv
        self.env = env
        self.log_path = log_path
        self.echo = echo
        self.process: subprocess.Popen[str] | None = None
        self.tail: deque[str] = deque(maxlen=20)
        self.starts = 0
        self._pump: threading.Thread | None = None
        self._ready = threading.Event()

    @property
    def name(self) -> str:
        return self.spec.name

    def start(self) -> None:
        self.starts += 1
        self._ready.clear()
        # Handed to the thread that copies the process's output; it closes it at the end.
        log = open(self.log_path, 'a')  # noqa: SIM115
        log.write(f'--- start {self.starts}: {" ".join(self.argv)}\n')
        log.flush()
        self.process = subprocess.Popen(self.argv, env=self.env, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, bufsize=1,
                                        start_new_session=True, pass_fds=self.inherited_fds)
        self._pump = threading.Thread(target=self._copy_output, args=(self.process, log),
                                      daemon=True)
        self._pump.start()

    def _copy_output(self, process: subprocess.Popen[str], log: TextIO) -> None:
        assert process.stdout is not None
        with log:
            for line in process.stdout:
                log.write(line)
                log.flush()
                self.tail.append(line.rstrip())
                if ' ready' in line:   # every node logs "<what> ready: ..." when set up
                    self._ready.set()
                if self.echo is not None:
                    self.echo(f'[{self.name}] {line.rstrip()}')

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait until the current start of the node has logged that it is ready."""
        return self._ready.wait(timeout_s)

    def exit_code(self) -> int | None:
        return None if self.process is None else self.process.poll()

    def join_output(self) -> None:
        """Wait (briefly) until the dead process's last lines are in the log and the tail."""
        if self._pump is not None:
            self._pump.join(timeout=2.0)

    def signal(self, sig: int) -> None:
        if self.process is not None and self.process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                self.process.send_signal(sig)

    def wait(self, timeout_s: float) -> bool:
        """True once the process has exited (within ``timeout_s``)."""
        if self.process is None:
            return True
        try:
            self.process.wait(max(timeout_s, 0.0))
        except subprocess.TimeoutExpired:
            return False
        return True


def stop_together(processes: list[NodeProcess], grace_s: float = 5.0) -> dict[str, int | None]:
    """SIGINT to all at once, then SIGTERM, then SIGKILL to whoever is left after each grace
    period; returns their exit codes. Every node stops on its first signal within a second, so
    the later steps are for a node that hangs."""
    for sig, wait_s in ((signal.SIGINT, grace_s), (signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0)):
        alive = [p for p in processes if p.exit_code() is None]
        if not alive:
            break
        for process in alive:
            process.signal(sig)
        deadline = time.monotonic() + wait_s
        for process in alive:
            process.wait(deadline - time.monotonic())
    for process in processes:
        process.join_output()
    return {process.name: process.exit_code() for process in processes}


SHM = Path('/dev/shm')


def shared_memory_files() -> set[str]:
    return {path.name for path in SHM.glob('*fastrtps*')} if SHM.is_dir() else set()


def clean_shared_memory(before: set[str]) -> None:
    """Remove Fast DDS shared-memory files this run left behind.

    `fastdds shm clean` removes segments and ports whose owner died (a SIGKILL leaves them).
    It leaves port files with no `_el` lock file: nobody listens on those any more, yet they
    stay in /dev/shm. Those are removed too, but only ones that appeared during this run.
    """
    tool = shutil.which('fastdds', path=str(Path(sys.prefix) / 'bin'))
    if tool:
        subprocess.run([tool, 'shm', 'clean'], stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL, timeout=30, check=False)
    for name in shared_memory_files() - before:
        if name.startswith('fastrtps_port') and not name.endswith('_el') \
                and not (SHM / f'{name}_el').exists():
            for leftover in (SHM / name, SHM / f'sem.{name}_mutex'):
                leftover.unlink(missing_ok=True)


@dataclass
class GraphOptions:
    goal_m: tuple[float, float]
    seed: int = 0
    real_time_factor: float = 1.0         # math.inf: as fast as the lockstep allows
    lockstep: bool = True                 # False: the dynamics runs free at the factor
    open_loop_s: float | None = None
    params_file: Path | None = None
    timeout_s: float = 600.0
    log_dir: Path = Path('out/runs')
    echo: Callable[[str], None] | None = None
    nodes: list[NodeSpec] | None = None
    domain_id: int | None = None
    follow_route: bool = False
    record: Path | None = None
    storage: str = 'mcap'
    force: bool = False
    # More goals after the first, each sent once the previous one is reached (the soak).
    more_goals_m: list[tuple[float, float]] = field(default_factory=list)
    respawn: bool = False                 # restart a crashed vision or controller node
    vision_overrides: dict[str, object] = field(default_factory=dict)
    controller_overrides: dict[str, object] = field(default_factory=dict)
    dynamics_overrides: dict[str, object] = field(default_factory=dict)
    # Called once the clock runs, with the Graph (tests use it to kill a node mid-run).
    on_running: Callable[[Graph], None] | None = None
    markers: bool = True                  # markers_node draws the run on /markers
    view: tuple[str, int] | None = None   # serve the topics to Foxglove on (host, port)
    vision: str = 'model'                 # 'images': camera_node + tracker_node (VISION_MODES)
    record_images: bool = False           # the recorder keeps the images too


@dataclass
class GraphResult:
    outcome: str
    reason: str
    periods: int
    final_x_m: float
    final_y_m: float
    final_phi_rad: float
    goal_m: tuple[float, float]
    sim_time_s: float
    wall_time_s: float
    log_dir: Path
    domain_id: int
    status: dict[str, str]
    route: list[tuple[float, float, float]] = field(default_factory=list)       # t, x, y
    captures: list[tuple[float, float, float, str]] = field(default_factory=list)  # t, x, y, cam
    goals: list[dict[str, str]] = field(default_factory=list)   # final status of every goal
    published: dict[str, int] = field(default_factory=dict)     # per topic, all nodes
    memory_kb: dict[str, list[int]] = field(default_factory=dict)  # RSS after each goal
    respawns: dict[str, int] = field(default_factory=dict)

    @property
    def deviation_m(self) -> float:
        return math.hypot(self.final_x_m - self.goal_m[0], self.final_y_m - self.goal_m[1])

    def as_json(self) -> dict[str, object]:
        return {
            'outcome': self.outcome, 'reason': self.reason, 'periods': self.periods,
            'final_x_mm': self.final_x_m * 1e3, 'final_y_mm': self.final_y_m * 1e3,
            'final_phi_deg': math.degrees(self.final_phi_rad),
            'deviation_mm': self.deviation_m * 1e3,
            'goal_x_mm': self.goal_m[0] * 1e3, 'goal_y_mm': self.goal_m[1] * 1e3,
            'sim_time_s': self.sim_time_s, 'wall_time_s': self.wall_time_s,
            'real_time_factor': (self.sim_time_s / self.wall_time_s
                                 if self.wall_time_s > 0 else None),
            'log_dir': str(self.log_dir), 'domain_id': self.domain_id,
        }


def _node_overrides(spec: NodeSpec, options: GraphOptions) -> dict[str, object]:
    overrides: dict[str, object] = {}
    if spec.executable == 'dynamics_node':
        # Time 0 waits until the orchestration has seen every node listening.
        overrides.update(paused=True, real_time_factor=float(options.real_time_factor))
        taking_part = [other.name for other in all_specs(options) if other.reports_lockstep]
        overrides.update(lockstep_nodes=taking_part if options.lockstep else [])
        overrides.update(options.dynamics_overrides)
    elif spec.executable in ('vision_node', 'camera_node'):
        overrides.update(seed=int(options.seed))
        overrides.update(options.vision_overrides)
    elif spec.executable == 'markers_node':
        # The fields as the camera in use has them (camera_node has vision_node's names).
        vision = node_parameters('omni_micro_vision', _camera_node(options), options,
                                 options.vision_overrides)
        dynamics = node_parameters('omni_micro_sim', 'dynamics_node', options,
                                   options.dynamics_overrides)
        controller = node_parameters('omni_micro_control', 'controller_node', options,
                                     options.controller_overrides)
        overrides.update({name: vision[name] for name in MARKERS_FROM_VISION if name in vision})
        for name, source in (('robot.wheel_offsets_rad', dynamics), ('tolerance_m', controller)):
            if name in source:
                overrides[name] = source[name]
    elif spec.executable == 'controller_node':
        if options.open_loop_s is not None:
            overrides.update(open_loop_duration_s=float(options.open_loop_s))
        overrides.update(options.controller_overrides)
    overrides.update(spec.overrides)
    return overrides


def graph_nodes(options: GraphOptions) -> list[NodeSpec]:
    """The nodes closing the loop: those given, else the default set for ``options.vision``."""
    return list(options.nodes or default_nodes(options.vision))


def streaming_cameras(options: GraphOptions) -> tuple[str, ...]:
    """The cameras whose images camera_node streams in this graph (none without it)."""
    if 'camera_node' not in {spec.executable for spec in graph_nodes(options)}:
        return ()
    values = node_parameters('omni_micro_vision', 'camera_node', options,
                             options.vision_overrides)
    cameras = values.get('cameras', ['macro', 'micro'])
    return tuple(str(name) for name in cameras) if isinstance(cameras, (list, tuple)) else ()


def all_specs(options: GraphOptions) -> list[NodeSpec]:
    """Every process of the graph: the loop, then who listens (markers, recorder, viewer)."""
    specs = graph_nodes(options)
    if options.markers:
        specs.append(MARKERS_NODE)
    if options.record is not None:
        images = streaming_cameras(options) if options.record_images else ()
        if options.record_images and not images:
            raise UsageError('--record-images needs the rendered cameras (--vision images)')
        # /camera/status is vision_node's (the tracker says why per camera, not recorded).
        unpublished = () if any(spec.executable == 'vision_node' for spec in specs) \
            else ('/camera/status',)
        specs.append(recorder_spec(options.record, options.storage, options.markers, images,
                                   unpublished))
    if options.view is not None:
        specs.append(viewer_spec(*options.view, options.markers))
    return specs


def _camera_node(options: GraphOptions) -> str:
    names = {spec.executable for spec in graph_nodes(options)}
    return 'camera_node' if 'camera_node' in names and 'vision_node' not in names \
        else 'vision_node'


def node_parameters(package: str, node: str, options: GraphOptions,
                    overrides: dict[str, object]) -> dict[str, object]:
    """A node's parameters as it will have them: its package file, the user's --params file,
    then the orchestration's overrides (dotted names, as -p gives them)."""
    values = params_from_files(package, node, options.params_file)
    values.update(overrides)
    return values


def params_from_files(package: str, node: str, params_file: Path | None) -> dict[str, object]:
    """A node's parameters from its package file, then ``params_file`` (dotted names)."""
    import yaml

    def flatten(tree: dict, prefix: str = '') -> dict[str, object]:
        flat: dict[str, object] = {}
        for key, value in tree.items():
            if isinstance(value, dict):
                flat.update(flatten(value, f'{prefix}{key}.'))
            else:
                flat[f'{prefix}{key}'] = value
        return flat

    values: dict[str, object] = {}
    files = [package_params_file(package, node)]
    if params_file is not None:
        files.append(params_file)
    for path in files:
        content = yaml.safe_load(Path(path).read_text()) or {}
        for name in (node, f'/{node}', '/**'):
            section = content.get(name, {}).get('ros__parameters', {})
            values.update(flatten(section))
    return values


def _argv(spec: NodeSpec, options: GraphOptions) -> list[str]:
    if spec.command is not None:
        return list(spec.command)
    argv = [str(resolve_executable(spec.package, spec.executable)), '--ros-args',
            '--params-file', str(package_params_file(spec.package, spec.executable))]
    if options.params_file is not None:
        argv += ['--params-file', str(options.params_file)]
    for name, value in _node_overrides(spec, options).items():
        argv += ['-p', f'{name}:={format_parameter(value)}']
    return argv


def node_environment(domain_id: int, log_dir: Path, images: bool = False) -> dict[str, str]:
    """The environment of a graph's processes; with ``images`` (camera frames flowing) the
    project's Fast DDS profile too, unless the user set one (config/fastdds.xml says why)."""
    env = dict(os.environ)
    env.update(ROS_DOMAIN_ID=str(domain_id), ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
               ROS_LOG_DIR=str(log_dir / 'ros'), PYTHONUNBUFFERED='1',
               RCUTILS_COLORIZED_OUTPUT='0')
    env.pop('ROS_LOCALHOST_ONLY', None)
    if images and not env.get('FASTRTPS_DEFAULT_PROFILES_FILE'):
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(dds_profile())
    return env


def dds_profile() -> Path:
    """The Fast DDS profile for graphs that carry camera frames (installed with omni_micro_sim)."""
    for prefix in install_prefixes():
        path = prefix / 'share' / 'omni_micro_sim' / 'config' / 'fastdds.xml'
        if path.is_file():
            return path
    raise RunFailed('config/fastdds.xml of omni_micro_sim is not installed')


class Graph:
    """The running processes of one graph, stopped in order however the run ends."""

    RESPAWNABLE = ('vision_node', 'controller_node')

    def __init__(self, options: GraphOptions, domain_id: int, log_dir: Path,
                 lease_fd: int | None = None) -> None:
        self.options = options
        self.domain_id = domain_id
        self.log_dir = log_dir
        self.shm_before = shared_memory_files()
        env = node_environment(domain_id, log_dir, images=bool(streaming_cameras(options)))
        # Only this process holds the write end (os.pipe() fds are not inherited); the read end
        # goes to every child, which stops when it reads end-of-file.
        self._lifeline_read, self._lifeline_write = os.pipe()
        env[LIFELINE_ENV] = str(self._lifeline_read)
        inherited = (self._lifeline_read,) + (() if lease_fd is None else (lease_fd,))
        specs = all_specs(options)
        if options.respawn:
            specs = [replace(spec, respawn=True) if spec.name in self.RESPAWNABLE else spec
                     for spec in specs]
        self.processes = [NodeProcess(spec, _argv(spec, options), env,
                                      log_dir / f'{spec.name}.log', options.echo, inherited)
                          for spec in specs]

    def process(self, name: str) -> NodeProcess:
        return next(p for p in self.processes if p.name == name)

    def wait_ready(self, name: str, timeout_s: float) -> bool:
        return self.process(name).wait_ready(timeout_s)

    def start(self) -> None:
        for process in self.processes:
            process.start()

    def check_alive(self) -> list[str]:
        """Restart dead nodes that respawn and return their names; raise for any other death.

        Raises
        ------
        UsageError
            A node refused its parameters (exit code 2): the message is the node's own.
        RunFailed
            A node died; the message names it and quotes the end of its log.
        """
        restarted = []
        for process in self.processes:
            code = process.exit_code()
            if code is None:
                continue
            process.join_output()
            tail = '\n  '.join(process.tail) or '(no output)'
            if code == 2 and process.starts == 1:
                raise UsageError(f'{process.name} refused its parameters:\n  {tail}')
            if process.spec.respawn:
                if self.options.echo:
                    self.options.echo(f'[orchestration] {process.name} exited with {code}; '
                                      f'respawning it')
                process.start()
                restarted.append(process.name)
                continue
            if self.options.echo:
                self.options.echo(f'[orchestration] {process.name} exited with code {code}; '
                                  f'stopping the graph')
            raise RunFailed(f'{process.name} exited with code {code} before the outcome; '
                            f'its log ({process.log_path}) ends:\n  {tail}')
        return restarted

    def memory_kb(self) -> dict[str, int]:
        """Resident memory of each live node process (VmRSS, kB)."""
        sizes = {}
        for process in self.processes:
            if process.process is None or process.exit_code() is not None:
                continue
            try:
                status = Path(f'/proc/{process.process.pid}/status').read_text()
            except OSError:
                continue
            for line in status.splitlines():
                if line.startswith('VmRSS:'):
                    sizes[process.name] = int(line.split()[1])
        return sizes

    def _cut_lifeline(self) -> None:
        for fd in (self._lifeline_read, self._lifeline_write):
            if fd >= 0:
                os.close(fd)
        self._lifeline_read = self._lifeline_write = -1

    def stop(self) -> dict[str, int | None]:
        """Stop every node, phase by phase; returns their exit codes (-9: it needed SIGKILL)."""
        started = time.monotonic()
        named = {name for phase in SHUTDOWN_PHASES if phase for name in phase}
        codes: dict[str, int | None] = {}
        for phase in SHUTDOWN_PHASES:
            members = [p for p in self.processes
                       if (p.name in phase if phase else p.name not in named)]
            codes.update(stop_together(members))
        self._cut_lifeline()
        if self.options.echo:
            self.options.echo(f'[orchestration] graph stopped in '
                              f'{time.monotonic() - started:.2f} s; exit codes: '
                              + ', '.join(f'{name} {code}' for name, code in codes.items()))
        clean_shared_memory(self.shm_before)
        record = self.options.record
        if record is not None and record.is_dir() and not (record / 'metadata.yaml').exists():
            self._recover_bag(record)
        return codes

    def _recover_bag(self, bag: Path) -> None:
        """The recorder died: turn what it flushed into a readable bag at the same path."""
        from omni_micro_tools.bags import recover

        torn = bag.with_name(bag.name + '.torn')
        shutil.rmtree(torn, ignore_errors=True)
        bag.rename(torn)
        try:
            counts = recover(torn, bag)
        except Exception as error:
            torn.rename(bag)
            if self.options.echo:
                self.options.echo(f'[orchestration] could not recover {bag}: {error}')
            return
        shutil.rmtree(torn)
        if self.options.echo:
            self.options.echo(f'[orchestration] the recorder died; recovered '
                              f'{sum(counts.values())} messages into {bag}')

    def published(self) -> dict[str, int]:
        """What the nodes say they published (their last log line), summed per topic."""
        totals: dict[str, int] = {}
        for process in self.processes:
            if not process.log_path.exists():
                continue
            for line in process.log_path.read_text().splitlines():
                if line.startswith(PUBLISHED_MARKER):
                    for topic, count in json.loads(line[len(PUBLISHED_MARKER):]).items():
                        totals[topic] = totals.get(topic, 0) + count
        return totals


def _new_log_dir(root: Path) -> Path:
    stamp = time.strftime('%Y%m%d-%H%M%S')
    folder = root / f'{stamp}-{os.getpid()}'
    suffix = 0
    while folder.exists():
        suffix += 1
        folder = root / f'{stamp}-{os.getpid()}-{suffix}'
    folder.mkdir(parents=True)
    return folder


def run_graph(options: GraphOptions) -> GraphResult:
    """Run the graph to the controller's outcome and return it with the true final pose.

    Raises
    ------
    UsageError
        A bad params file, an existing bag path, or a node refusing its parameters.
    RunFailed
        If a node died, the graph did not come up, or no outcome came within the timeout; the
        message names the node and where its log is.
    """
    from omni_micro_cli.orchestration.monitor import GraphMonitor  # rclpy only where a graph runs

    if options.params_file is not None:
        check_params_file(options.params_file)
    if options.record is not None:
        from omni_micro_tools.bags import check_output_path

        check_output_path(options.record, options.force)
    log_dir = _new_log_dir(options.log_dir)
    goals = [(float(x), float(y)) for x, y in [options.goal_m, *options.more_goals_m]]
    lease = DomainLease(options.domain_id)
    with lease as domain_id:
        graph = Graph(options, domain_id, log_dir, lease.fileno)
        monitor = GraphMonitor(domain_id, follow_route=options.follow_route)
        recording = options.record is not None
        statuses = []
        memory: dict[str, list[int]] = {}
        try:
            graph.start()
            monitor.wait_until_ready(graph, timeout_s=60.0, recording=recording,
                                     markers=options.markers,
                                     images=streaming_cameras(options))
            wall_start = time.monotonic()
            for index, goal in enumerate(goals):
                monitor.send_goal(graph, goal, recording)
                if index == 0:
                    wall_start = time.monotonic()
                    monitor.set_paused(False)
                    if options.on_running is not None:
                        options.on_running(graph)
                status = monitor.wait_for_outcome(graph, options.timeout_s, goal, recording)
                statuses.append(status)
                for name, size in graph.memory_kb().items():
                    memory.setdefault(name, []).append(size)
                if status['outcome'] not in ('reached', 'completed'):
                    break
            wall_time = time.monotonic() - wall_start
            capture_stamp = float(status.get('capture_stamp_s', '0'))
            odom = monitor.wait_for_odometry_after(graph, capture_stamp, timeout_s=30.0)
        finally:
            monitor.close()
            graph.stop()
    published = graph.published()
    published['/goal_pose'] = monitor.goals_sent
    return GraphResult(
        outcome=status['outcome'], reason=status.get('reason', ''),
        periods=int(status.get('periods', '0')), final_x_m=odom[1], final_y_m=odom[2],
        final_phi_rad=odom[3], goal_m=goals[len(statuses) - 1],
        sim_time_s=float(status.get('sim_time_s', 'nan')), wall_time_s=wall_time,
        log_dir=log_dir, domain_id=domain_id, status=status, route=monitor.route,
        captures=monitor.captures, goals=statuses, published=published, memory_kb=memory,
        respawns={p.name: p.starts - 1 for p in graph.processes if p.starts > 1})

