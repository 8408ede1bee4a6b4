"""What the orchestrator waits for before it starts the clock (:func:`readiness`), for one robot
or several, simulated or on the bench: who must read which topics, what the bench's drivers must
publish, and whether a simulated robot keeps the clock."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from omni_micro_bringup.composition import (
    bench_cameras,
    graph_nodes,
    streaming_cameras,
    tracked_cameras,
)
from omni_micro_bringup.graph_options import GraphOptions
from omni_micro_bringup.robot_namespaces import robot_names
from omni_micro_common.topic_names import (
    CAPTURE_COVARIANCE_TOPICS,
    CAPTURE_TOPICS,
    JOINT_STATES_TOPIC,
    ODOM_TOPIC,
    WHEEL_TRAJECTORY_TOPIC,
    namespaced_topic,
)

# What a real robot's driver must publish for the loop (it reads /wheel_trajectory).
EXTERNAL_ROBOT_PUBLISHES = (JOINT_STATES_TOPIC,)


@dataclass(frozen=True)
class Readiness:
    """What a graph must show before its run starts."""

    subscriptions: list[tuple[str, ...]]   # topics someone must read (of alternatives, any one)
    publications: dict[str, str]           # topic -> who must publish it (the bench's drivers)
    images: tuple[str, ...]                # the cameras whose images the tracker must read
    markers: tuple[str, ...]               # the namespaces whose markers_node must read goals
    recording: bool                        # the recorder must have matched every publisher
    clock: bool                            # a simulated robot's clock must be startable


def readiness(options: GraphOptions) -> Readiness:
    """What the graph of ``options`` must show before its run starts, for every robot."""
    return Readiness(subscriptions=ready_subscriptions(options),
                     publications=external_publications(options),
                     images=streaming_cameras(options),
                     markers=tuple(robot_names(options)) if options.markers else (),
                     recording=options.record is not None, clock=simulates_robot(options))


def simulates_robot(options: GraphOptions) -> bool:
    return any(spec.executable == 'dynamics_node' for spec in graph_nodes(options))


def ready_subscriptions(options: GraphOptions) -> list[tuple[str, ...]]:
    """The topics someone must read before time may start (of alternatives, any one):
    :func:`loop_subscriptions` of every robot (a single robot's in the root namespace), of the
    cameras whose captures the graph publishes, the robots' odometry if a simulated camera
    (vision_node, camera_node) is in the graph."""
    names = {spec.executable for spec in graph_nodes(options)}
    return loop_subscriptions(odometry=bool(names & {'vision_node', 'camera_node'}),
                              cameras=tracked_cameras(options), robots=robot_names(options))


def loop_subscriptions(odometry: bool, cameras: Sequence[str] = tuple(CAPTURE_TOPICS),
                       robots: Sequence[str] = ('',)) -> list[tuple[str, ...]]:
    """What one robot's loop must read before time may start (of alternatives, any one): the
    robot its trajectories, the controller the wheels and the captures of ``cameras`` (bare or
    with their covariance, as its capture_uncertainty says: either will do), with ``odometry``
    a simulated camera the robot's odometry; each of ``robots``' own, in its namespace (``''``
    the root one)."""
    topics = [(WHEEL_TRAJECTORY_TOPIC,), (JOINT_STATES_TOPIC,),
              *(((ODOM_TOPIC,),) if odometry else ()),
              *((CAPTURE_TOPICS[camera], CAPTURE_COVARIANCE_TOPICS[camera]) for camera in cameras)]
    return [tuple(namespaced_topic(robot, topic) for topic in alternatives) for robot in robots
            for alternatives in topics]


def external_publications(options: GraphOptions) -> dict[str, str]:
    """Topics the bench's drivers must publish, each with who should (the run waits for them
    and names the one missing)."""
    needed = {}
    if options.robot == 'external':
        needed.update({namespaced_topic(robot, topic): f"{robot}'s driver" if robot
                       else "the robot's driver"
                       for robot in robot_names(options) for topic in EXTERNAL_ROBOT_PUBLISHES})
    needed.update({topic: 'the camera driver' for topic in bench_cameras(options).values()})
    return needed
