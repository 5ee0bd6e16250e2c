"""Zenoh as a :class:`fogiac.net.middleware.Middleware`: ROS 2's way across (rmw_zenoh)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from fogiac.hostmodel import Launching
from fogiac.msgtypes import DEFAULT_MATCH
from fogiac.net.zenoh.config import LOCAL_PORT as LOCAL_PORT  # re-exported: the ports in one place
from fogiac.net.zenoh.config import ROUTER_PORT

ROUTER = "zenoh-router"  # the host's router service, which nodes start after


def instance_args(robot: str, topics: tuple[str, ...]) -> tuple[str, ...]:
    """ROS 2's command-line arguments (rclcpp and rclpy read them, ``ros2 run`` passes them on) for a node's
    instance serving ``robot``: its namespace ``/<robot>`` and each listed topic remapped into it
    (``-r /scan:=/arm1/scan``), in a ``--ros-args`` block of their own (a command may hold one already). The
    fleet's routers let robot ``arm1`` cross ``/arm1/...`` only, so its topics reach this instance alone."""
    remaps = (f"__ns:=/{robot}", *(f"{topic}:=/{robot}{topic}" for topic in sorted(set(topics))))
    return ("--ros-args", *(arg for remap in remaps for arg in ("-r", remap)))


@dataclass(frozen=True)
class ZenohMiddleware:
    name: str = "zenoh"
    distros: tuple[str, ...] = ("humble", "jazzy", "kilted")
    port: int = ROUTER_PORT
    label: str = "Zenoh: routers over mutual TLS, per-topic access control, the edge dials out"
    edge_side: str = "Zenoh edge router (dials out; rmw_zenoh nodes or zenoh-bridge-ros2dds connect to it)"
    cloud_side: str = "Zenoh router per host (mutual TLS, access control: the manifest's topics only)"
    rule_description: str = "Zenoh router (mutual TLS)"
    credentials_first: bool = True  # the router starts before the nodes, with its certificate
    node_master: bool = False  # ROS 2 has no master: a node is up while its process runs
    nodes_after: str = ROUTER  # rmw_zenoh nodes find their host's router at start
    host_requirements: tuple[str, ...] = ("eclipse-zenoh==1.10.2",)  # the router's; pyproject's ros2 extra pins it too
    # colcon installs each package under install/, whose setup.bash (over the distro's) lets
    # `ros2 launch` find it; the ros-core images lack colcon (ros-base has it).
    block: type[Any] | None = None  # its settings are the manifest's shared relay: block (compile reads it)
    launching: Launching = Launching(
        command=("ros2", "launch"), has_packages='[ -n "$(find src -name package.xml -print -quit 2>/dev/null)" ]',
        tool="colcon", build="colcon build", overlay="install/setup.bash", package_path=False, image_has_tool=False,
        instance_args=instance_args)

    def edge_entry(self, edge: Any) -> str:
        return str(edge.zenoh_router)

    def robot_certificate(self, stack: str, robot: str) -> str:
        """The common name of a fleet robot's edge router certificate (:func:`fogiac.net.zenoh.tls.edge_name`, which
        imports the certificates' code: the plan names it without)."""
        return f"{robot}.edge.router.{stack}.fogiac"

    def manifest_problems(self, manifest: Any) -> tuple[tuple[str, str], ...]:
        """Access control allows exactly the listed topics: a node whose topics are "auto" has none. The replica
        merge reads a reply's key where a CDR ``header.stamp`` is (rmw_zenoh sends no message definition to
        find any other field by): a replicated node matching by anything else would have its replies keyed by
        bytes that are not its field, so it is refused. A fleet's shared node with replicas is refused too: each
        robot links to a router of its own behind each host's gate (:mod:`fogiac.net.zenoh.gate`) and may cross
        its own namespace only, which a replica's keys (``fogiac/replica/...``) are outside, and no fleet
        process carries a robot's requests to a replica; a per-robot node's replicas are refused by the schema."""
        auto = [(f"ROS {manifest.ros.distro} crosses through {self.name}, whose access control allows only "
                 "listed topics: give this node topics: {in: [...], out: [...]}", f"nodes[{i}].topics")
                for i, node in enumerate(manifest.nodes) if node.topics == "auto"]
        match = [(f"{node.reply_match!r}: over {self.name} (ROS {manifest.ros.distro}) replicas' replies are matched "
                  f"by {DEFAULT_MATCH} only (rmw_zenoh sends no message definition to find another field by); "
                  f"give the reply a std_msgs/Header copied from its request", f"nodes[{i}].reply_match")
                 for i, node in enumerate(manifest.nodes) if node.replicas > 1 and node.reply_match != DEFAULT_MATCH]
        fleet = [(f"replicas: {node.replicas} in a fleet (robots:) over {self.name} (ROS {manifest.ros.distro}) is "
                  "not built: a robot crosses only its own namespace, which a replica's keys are outside; give "
                  "replicas: 1 or one robot (edge:)", f"nodes[{i}].replicas")
                 for i, node in enumerate(manifest.nodes)
                 if manifest.robots and node.replicas > 1 and node.serve != "per_robot"]
        return tuple(auto + match + fleet)


ZENOH = ZenohMiddleware()
