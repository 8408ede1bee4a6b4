"""What a run through the graph is asked to do: one robot's goals, or several robots' plan
(:class:`FleetRun`), and how the graph runs them (:class:`GraphOptions`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from omni_micro_bringup.node_spec import NodeSpec
from omni_micro_control.fleet_guard import STOP_GAP_M, UNNAMED_S
from omni_micro_control.fleet_plan import FleetPlan
from omni_micro_sim.parameters import RobotParameters


@dataclass(frozen=True)
class FleetRun:
    """What several robots' run adds to a graph's options: the plan of their legs, each
    robot's true robot (``robots[k]``) and controller mode, and how much simulated time it may
    take (looked at as goals end)."""

    plan: FleetPlan
    robots: list[RobotParameters]
    controllers: list[str]
    max_sim_time_s: float = 1800.0
    # Called as each leg that ends tasks ends: (tasks done, tasks in all, simulated time).
    on_progress: Callable[[int, int, float], None] | None = None
    # Real robots on the bench (omni_micro_control.fleet_guard): every robot stopped once two
    # would come closer than ``stop_gap_m``, or one driving goes ``unnamed_s`` unnamed.
    stop_gap_m: float = STOP_GAP_M
    unnamed_s: float = UNNAMED_S


@dataclass
class GraphOptions:
    """A run through the graph: one robot in the root namespace driven to ``goal_m`` (and
    ``more_goals_m``), or with ``fleet`` several under /robot_k, each driven along its legs."""

    goal_m: tuple[float, float] | None = None
    seed: int = 0
    real_time_factor: float = 1.0         # math.inf: as fast as the lockstep allows
    lockstep: bool = True                 # False: the dynamics runs free at the factor
    open_loop_s: float | None = None
    # The user's params files, each after the packages' own (later files win, as ROS does).
    params_files: tuple[Path, ...] = ()
    timeout_s: float = 600.0
    log_dir: Path = Path('out/runs')
    echo: Callable[[str], None] | None = None
    nodes: list[NodeSpec] | None = None
    domain_id: int | None = None
    follow_route: bool = False
    record: Path | None = None
    storage: str = 'mcap'
    # The bag keeps every message received, not only up to its last outcome and a tail (the
    # soak counts them against what was published).
    record_whole: bool = False
    force: bool = False
    # More goals after the first, each sent once the previous one is reached (the soak).
    more_goals_m: list[tuple[float, float]] = field(default_factory=list)
    respawn: bool = False                 # restart a crashed vision or controller node
    vision_overrides: dict[str, object] = field(default_factory=dict)
    controller_overrides: dict[str, object] = field(default_factory=dict)
    dynamics_overrides: dict[str, object] = field(default_factory=dict)
    markers: bool = True                  # markers_node draws the run on /markers
    view: tuple[str, int] | None = None   # serve the topics to Foxglove on (host, port)
    vision: str = 'model'                 # 'images': camera_node + tracker_node (VISION_MODES)
    record_images: bool = False           # the recorder keeps the images too
    # vision_node publishes captures of the moving robot too (and the recorder keeps them); the
    # servo mode reads them, so with it they are on whatever this says (publishes_in_motion).
    captures_in_motion: bool = False
    # The loop's nodes in processes of omni_micro_common's container, each with one executor:
    # ``containers`` of them (node_spec.composed says which nodes each hosts; None: it chooses).
    composed: bool = False
    containers: int | None = None
    # A real camera driver (its images to tracker_node) or a real robot (its driver reads
    # /wheel_trajectory and publishes /joint_states) instead of the simulated one: then every
    # node runs on the wall clock, free, at real time.
    camera: str = 'simulated'
    robot: str = 'simulated'
    # With an external camera: the driver's image topic per tracker camera (its CameraInfo
    # beside it); empty: the tracker's params say.
    image_topics: dict[str, str] = field(default_factory=dict)
    fleet: FleetRun | None = None

    @property
    def external(self) -> bool:
        return 'external' in (self.camera, self.robot)

    @property
    def in_lockstep(self) -> bool:
        """Whether time waits for the nodes' reports (nothing real reports on /lockstep)."""
        return self.lockstep and not self.external
