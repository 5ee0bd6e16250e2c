"""Zenoh as a :class:`fogiac.net.middleware.Middleware`: ROS 2's way across (rmw_zenoh)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fogiac.errors import ProvisionError
from fogiac.manifest.schema import Edge
from fogiac.net.zenoh import deploy
from fogiac.net.zenoh.config import LOCAL_PORT as LOCAL_PORT  # re-exported: the ports in one place
from fogiac.net.zenoh.config import ROUTER_PORT
from fogiac.plan.model import HostSpec, Plan
from fogiac.provision.host import Host
from fogiac.provision.services import Service, Where


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
    credentials_first: bool = True  # the router starts before the nodes, with its certificate
    host_requirements: tuple[str, ...] = ("eclipse-zenoh==1.10.2",)  # the router's; pyproject's ros2 extra pins it too

    def edge_entry(self, edge: Edge) -> str:
        return edge.zenoh_router

    def node_env(self, where: Where) -> Mapping[str, str]:
        return deploy.node_env(where)

    def host_services(self, plan: Plan, spec: HostSpec, where: Where, *, certs: Path | None) -> tuple[Service, ...]:
        if certs is None:
            raise ProvisionError(f"{spec.name}: the Zenoh router needs the stack's certificates")
        return deploy.host_services(plan, spec, where, certs=certs)

    def link_services(self, plan: Plan, spec: HostSpec, where: Where) -> tuple[Service, ...]:
        return ()  # the host's router (host_services) is the link

    def link_files(self) -> tuple[tuple[str, int], ...]:
        return ()

    def host_credentials(self, host: Host, *, python: str, folder: str, certs_dir: Path, plan: Plan,
                         spec: HostSpec, dialed: str) -> bool:
        return deploy.host_credentials(host, python=python, folder=folder, certs_dir=certs_dir, plan=plan, spec=spec,
                                       dialed=dialed)

    def prepare_edge(self, plan: Plan, entry: str, *, folder: Path, start: bool) -> None:
        """Nothing to check: ROS 2 has no master, and the edge router is fogiac's own."""

    def edge_up(self, plan: Plan, *, entry: str, connect: Mapping[str, str], certs: Path,
                folder: Path) -> list[str]:
        return deploy.edge_up(plan, entry=entry, connect=connect, certs=certs, folder=folder)

    def edge_links(self, plan: Plan, *, folder: Path, connect: Mapping[str, str]) -> list[dict[str, Any]]:
        return deploy.edge_links(plan, folder=folder, connect=connect)


ZENOH = ZenohMiddleware()
