"""The relay as a :class:`fogiac.net.middleware.Middleware`: ROS 1's way across."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fogiac.hostmodel import Launching
from fogiac.net.relay.config import RELAY_PORT

MASTER = "ros-master"  # the host's roscore service, which nodes and the relay's cloud end start after


def instance_args(robot: str, topics: tuple[str, ...]) -> tuple[str, ...]:
    """ROS 1's command-line arguments (rospy and roscpp read them) for a node's instance serving ``robot``:
    its namespace ``/<robot>`` (its node name and relative topics move there) and each listed topic remapped
    into it (``/scan:=/arm1/scan``), so the robot's access (its namespace) reaches this instance only."""
    return (f"__ns:=/{robot}", *(f"{topic}:=/{robot}{topic}" for topic in sorted(set(topics))))


@dataclass(frozen=True)
class RelayMiddleware:
    name: str = "relay"
    distros: tuple[str, ...] = ("noetic",)
    port: int = RELAY_PORT
    label: str = "fogiac relay: ROS 1 topics over one mutual-TLS link the edge opens"
    edge_side: str = "fogiac relay, edge end (dials out)"
    cloud_side: str = "fogiac relay, cloud end"
    rule_description: str = "fogiac relay (mutual TLS)"
    credentials_first: bool = False  # the cloud end starts at link, after the nodes
    node_master: bool = True  # a node is up once it registers with the host's roscore
    nodes_after: str = MASTER
    host_requirements: tuple[str, ...] = ()  # the cloud end needs fogiac's own requirements only
    # roslaunch --wait: without it, a roslaunch that starts before the host's master service would
    # start a master of its own on the same port and make the real one crash-loop. catkin_make
    # leaves devel/setup.bash, which puts the package's built messages and scripts where roslaunch looks.
    block: type[Any] | None = None  # its settings are the manifest's shared relay: block (compile reads it)
    launching: Launching = Launching(command=("roslaunch", "--wait"), has_packages="[ -f src/CMakeLists.txt ]",
                                     tool="catkin_make", build="catkin_make", overlay="devel/setup.bash",
                                     package_path=True, image_has_tool=True, instance_args=instance_args)

    def edge_entry(self, edge: Any) -> str:
        return str(edge.ros_master)

    def manifest_problems(self, manifest: Any) -> tuple[tuple[str, str], ...]:
        return ()  # the relay discovers topics ("auto") and carries any listed ones


RELAY = RelayMiddleware()
