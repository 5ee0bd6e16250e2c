"""Zenoh as a :class:`fogiac.net.middleware.Middleware`: ROS 2's way across (rmw_zenoh)."""

from __future__ import annotations

from dataclasses import dataclass

ROUTER_PORT = 7448  # the cloud router's mutual-TLS port for the edge (7447, rmw_zenoh's default, stays local)
LOCAL_PORT = 7447  # rmw_zenoh's default router port: where nodes on the same machine connect


@dataclass(frozen=True)
class ZenohMiddleware:
    name: str = "zenoh"
    distros: tuple[str, ...] = ("humble", "jazzy", "kilted")
    port: int = ROUTER_PORT
    label: str = "Zenoh: routers over mutual TLS, per-topic access control, the edge dials out"
    edge_side: str = "Zenoh edge router (dials out; rmw_zenoh nodes or zenoh-bridge-ros2dds connect to it)"
    cloud_side: str = "Zenoh router per host (mutual TLS, access control: the manifest's topics only)"
    rule_description: str = "Zenoh router (mutual TLS)"
    needs_listed_topics: bool = True  # access control allows exactly the listed topics


ZENOH = ZenohMiddleware()
